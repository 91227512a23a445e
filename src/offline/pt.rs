//! The reference path tracer (`--mode pt`): unidirectional path tracing with next-event
//! estimation on area and punctual lights, multiple importance sampling of light and BSDF
//! samples with the power heuristic (Veach 1997, §9.2), Russian roulette, and delta BSDFs
//! handled by flags. This is the estimator every other mode is checked against.

use glam::Vec3;

use crate::accel::{Accel, offset_origin};
use crate::bsdf::{Bsdf, TransportMode};
use crate::film::AovSample;
use crate::sampling::{Sampler, power_heuristic};
use crate::scene::{Ray, Scene};
use crate::stats::RayStats;

/// Bounces after which Russian roulette may end a path.
pub const RR_START: u32 = 3;

/// Estimates the radiance arriving at the camera along `ray` with at most `max_depth`
/// scattering events. Returns the estimate and the first-hit AOVs.
pub fn radiance(
    scene: &Scene,
    accel: &Accel,
    ray: Ray,
    sampler: &mut impl Sampler,
    max_depth: u32,
    stats: &mut RayStats,
) -> (Vec3, AovSample) {
    radiance_of_length(scene, accel, ray, sampler, max_depth, &PathFilter::default(), stats)
}

/// Restricts the paths an estimate counts, for comparing estimators on a common domain.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PathFilter {
    /// Only paths whose number of segments (camera to light) lies in this inclusive range.
    pub edges: Option<(u32, u32)>,
    /// Only paths whose second segment (first visible point x₁ to the next vertex x₂) is at
    /// least this long. Instant radiosity without clamping has infinite variance near x₁ = x₂
    /// (the 1/d² of G); on this domain both it and the path tracer have finite variance, so
    /// their agreement can be tested statistically.
    pub min_second_segment: f32,
    /// Only the direct part that `--mode mlt` path traces beside its chains
    /// (`mlt::in_direct_part`): paths whose camera-side vertices, all but the one next to the
    /// light, are delta (a light or a surface it lights directly, seen directly or through
    /// mirrors and glass), and paths with a delta vertex next to the light, one next to the
    /// camera and no two non-delta vertices adjacent (no edge a connection could make).
    pub mlt_direct_part: bool,
}

/// Where a camera walk stands against `--mode mlt`'s direct part (`mlt::in_direct_part`), from
/// the delta flags of its bounces so far x_1 … x_d (the walk at x_{d+1}).
#[derive(Clone, Copy, Debug)]
pub struct DirectPart {
    /// x_1 … x_d all delta.
    delta_chain: bool,
    /// x_1 … x_{d−1} all delta.
    delta_chain_before: bool,
    /// x_d delta (true before the first bounce).
    last_delta: bool,
    /// x_1 delta (true before the first bounce).
    first_delta: bool,
    /// No two adjacent vertices of x_1 … x_d non-delta.
    no_adjacent_nondelta: bool,
    bounces: u32,
}

impl Default for DirectPart {
    fn default() -> Self {
        DirectPart {
            delta_chain: true,
            delta_chain_before: true,
            last_delta: true,
            first_delta: true,
            no_adjacent_nondelta: true,
            bounces: 0,
        }
    }
}

impl DirectPart {
    /// The walk scattered at its current vertex, with a delta lobe or not.
    pub fn bounce(&mut self, delta: bool) {
        if self.bounces == 0 {
            self.first_delta = delta;
        } else if !delta && !self.last_delta {
            self.no_adjacent_nondelta = false;
        }
        self.delta_chain_before = self.delta_chain;
        self.delta_chain &= delta;
        self.last_delta = delta;
        self.bounces += 1;
    }

    /// An emitter hit at x_{d+1} makes a path of the direct part: everything between the
    /// camera and x_d delta, or no edge a connection could make (x_1 and x_d delta, no two
    /// adjacent non-delta vertices).
    pub fn emitter_counts(&self) -> bool {
        self.delta_chain_before || (self.first_delta && self.last_delta && self.no_adjacent_nondelta)
    }

    /// Next-event estimation at x_{d+1} makes a path of the direct part (x_1 … x_d delta).
    pub fn nee_counts(&self) -> bool {
        self.delta_chain
    }

    /// Some later vertex of the walk can still make a path of the direct part.
    pub fn can_follow(&self) -> bool {
        self.delta_chain || (self.first_delta && self.no_adjacent_nondelta)
    }
}

/// [`radiance`] restricted by `filter`: emission found after d bounces has d + 1 edges,
/// next-event estimation after d bounces d + 2. Used to check bidirectional strategies length
/// by length and VPL estimators on a common domain.
pub fn radiance_of_length(
    scene: &Scene,
    accel: &Accel,
    ray: Ray,
    sampler: &mut impl Sampler,
    max_depth: u32,
    filter: &PathFilter,
    stats: &mut RayStats,
) -> (Vec3, AovSample) {
    let edges = filter.edges;
    let min_seg = filter.min_second_segment;
    let counts = |e: u32| edges.is_none_or(|(lo, hi)| (lo..=hi).contains(&e));
    let mut x1 = Vec3::ZERO;
    let mut l = Vec3::ZERO;
    let mut beta = Vec3::ONE;
    let mut aov = AovSample::default();
    let mut ray = ray;
    // Density of the BSDF sample that produced the current ray, for MIS with light sampling.
    let mut prev_pdf_w = 0.0f32;
    let mut prev_delta = true;
    let mut prev_p = ray.origin;
    let mut depth = 0u32;
    let mut part = DirectPart::default();
    let specular_only = filter.mlt_direct_part;
    loop {
        stats.closest += 1;
        let Some(hit) = accel.intersect(ray.origin, ray.dir, f32::INFINITY) else {
            // The ray leaves the scene: the lights at infinity along it (the sky, a soft sun),
            // weighed against next-event estimation as an emitter hit is.
            if !scene.lights.escaped.is_empty() && counts(depth + 1) && (!specular_only || part.emitter_counts()) {
                let le = scene.escaped(ray.dir);
                if le != Vec3::ZERO {
                    if depth == 0 || prev_delta {
                        l += beta * le;
                    } else {
                        l += beta * le * power_heuristic(prev_pdf_w, scene.pdf_li_escaped(ray.dir));
                    }
                }
            }
            break;
        };
        let sp = scene.surface_point(hit.tri, hit.b1, hit.b2);
        if depth == 0 {
            x1 = sp.p;
        } else if depth == 1 && min_seg > 0.0 && (sp.p - x1).length() < min_seg {
            break;
        }
        let wo = -ray.dir;
        let material = scene.material_of(hit.tri);

        // Emission seen along the ray: full weight for camera rays and after delta bounces,
        // otherwise MIS against next-event estimation.
        let le = scene.emitted(hit.tri, sp.ng, sp.uv, wo);
        if le != Vec3::ZERO && counts(depth + 1) && (!specular_only || part.emitter_counts()) {
            if depth == 0 || prev_delta {
                l += beta * le;
            } else {
                let pdf_light = scene.pdf_li(prev_p, hit.tri, sp.p, sp.ng);
                l += beta * le * power_heuristic(prev_pdf_w, pdf_light);
            }
        }

        let bsdf = Bsdf::new(material.bsdf_kind(sp.uv, &scene.textures), sp.ns, sp.ng, wo);
        if depth == 0 {
            aov = AovSample { albedo: bsdf.albedo(), normal: bsdf.frame.n, depth: hit.t, ..Default::default() };
        }
        if depth >= max_depth || edges.is_some_and(|(_, hi)| depth + 1 >= hi) {
            break;
        }
        let corners = scene.mesh.corners(hit.tri);

        // Next-event estimation.
        let u_light = sampler.next_1d();
        let u_light_pos = sampler.next_2d();
        if !bsdf.is_delta()
            && counts(depth + 2)
            && (!specular_only || part.nee_counts())
            && let Some(ls) = scene.sample_li(sp.p, u_light, u_light_pos)
            && (depth > 0 || ls.dist >= min_seg)
        {
            let f = bsdf.f(wo, ls.wi) * bsdf.abs_cos(ls.wi);
            if f != Vec3::ZERO && ls.li != Vec3::ZERO {
                let origin = offset_origin(&sp, &corners, ls.wi);
                stats.shadow += 1;
                if !accel.occluded(origin, ls.p - origin, 1.0 - 1e-4) {
                    let w = if ls.delta { 1.0 } else { power_heuristic(ls.pdf_w, bsdf.pdf_w(wo, ls.wi)) };
                    l += beta * f * ls.li * (w / ls.pdf_w);
                }
            }
        }

        // Once neither kind can follow, the path ends.
        if specular_only && !part.can_follow() {
            break;
        }
        // Continue the path by sampling the BSDF.
        let u_lobe = sampler.next_1d();
        let u_dir = sampler.next_2d();
        let Some(bs) = bsdf.sample(wo, u_lobe, u_dir, TransportMode::Radiance) else { break };
        beta *= bs.f * (bsdf.abs_cos(bs.wi) / bs.pdf_w);
        if beta == Vec3::ZERO || !beta.is_finite() {
            break;
        }
        part.bounce(bs.delta);
        prev_pdf_w = bs.pdf_w;
        prev_delta = bs.delta;
        prev_p = sp.p;
        depth += 1;
        ray = Ray { origin: offset_origin(&sp, &corners, bs.wi), dir: bs.wi };

        // Russian roulette (Arvo & Kirk 1990): survive with probability max component of beta.
        if depth >= RR_START {
            let q = beta.max_element().min(0.95);
            if sampler.next_1d() >= q {
                break;
            }
            beta /= q;
        }
    }
    (l, aov)
}
