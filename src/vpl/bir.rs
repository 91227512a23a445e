//! Bidirectional instant radiosity (after Segovia, Iehl, Mitanchey & Péroche 2006; papers/002
//! §7.4–7.5): R·m candidate VPLs from light sub-paths ("standard") and from camera sub-paths
//! ("reverse"), each candidate's power to the camera estimated at camera probes, and m VPLs kept
//! by importance resampling.
//!
//! mirage's formulation, chosen so the estimator is unbiased and every weight is computable:
//! * K camera probes x₁ (first non-specular hits of random camera rays) are shared by all steps.
//! * Standard candidates: SIR VPLs from R·m/2 worth of light paths.
//! * Reverse candidates: pick a probe uniformly, cosine-sample a direction, hit x₂ (a flat
//!   Lambertian surface; other hits are discarded). x₂'s location density is the mixture
//!   `p_E(x₂) = (1/K) Σ_k cos_k cos₂ / (π d_k²) · V_k` over all probes (K visibility rays), and its
//!   reflected radiance `ρ/π · E(x₂)` is estimated from a random subset of the standard VPLs.
//! * Combination: a reflected-light location x can come from both techniques only if it is a
//!   flat Lambertian point visible from some probe (the set S). Each technique gets weight ½ on S
//!   and the standard one weight 1 off S (standard VPLs test S with K visibility rays), so the
//!   weights sum to one everywhere. VPLs on lights always have weight 1.
//! * Resampling: candidate i has importance φ_i = Σ_k Y(contribution to probe k) plus 10 % of the
//!   mean (so no candidate that could matter has zero probability); m draws with replacement ∝ φ,
//!   each kept VPL scaled by Σφ / (m φ_i).

use std::f32::consts::FRAC_1_PI;
use std::time::Instant;

use glam::Vec3;

use super::cdf::camera_probes;
use super::set::{NO_LOBE, ON_LIGHT, Vpl, VplSet};
use super::sir::Sir;
use super::transfer::{Receiver, contribution};
use super::{SamplerStats, VplSampler};
use crate::accel::{Accel, offset_origin};
use crate::bsdf::{BsdfKind, Frame};
use crate::color::luminance;
use crate::sampling::{Distribution1D, IndependentSampler, Sampler, warp};
use crate::scene::{Camera, Scene};
use crate::stats::RayStats;

const TAG_REVERSE: u64 = 0x0042_4952_5f52_4556;
const TAG_RESAMPLE: u64 = 0x0042_4952_5f52_534d;

/// The BIR sampler.
#[derive(Debug)]
pub struct Bir {
    /// Standard VPL generator.
    pub sir: Sir,
    /// Candidates per kept VPL (R).
    pub resampling: usize,
    /// Camera probes (K).
    pub probes: usize,
    /// Standard VPLs used to estimate a reverse VPL's radiance.
    pub gather_subset: usize,
}

impl Bir {
    /// BIR with R = 10, K = 16 probes, light paths of at most `max_depth` vertices.
    pub fn new(max_depth: u32) -> Self {
        Bir { sir: Sir::new(max_depth), resampling: 10, probes: 16, gather_subset: 32 }
    }
}

fn visible(scene: &Scene, accel: &Accel, r: &Receiver, p: Vec3, stats: &mut RayStats) -> bool {
    let o = offset_origin(&r.sp, &scene.mesh.corners(r.sp.tri), p - r.sp.p);
    stats.shadow += 1;
    !accel.occluded(o, p - o, 1.0 - 1e-4)
}

/// Cosine-weighted density (area measure at x, normal n_x) of reaching x from probe r, with
/// visibility.
fn probe_density(scene: &Scene, accel: &Accel, r: &Receiver, x: Vec3, n_x: Vec3, stats: &mut RayStats) -> f32 {
    let d = x - r.sp.p;
    let d2 = d.length_squared();
    if !(d2 > 0.0) {
        return 0.0;
    }
    let w = d / d2.sqrt();
    let cos_r = r.bsdf.frame.n.dot(w);
    if cos_r <= 0.0 {
        return 0.0;
    }
    let cos_x = n_x.dot(-w).abs();
    if cos_x <= 0.0 || !visible(scene, accel, r, x, stats) {
        return 0.0;
    }
    cos_r * FRAC_1_PI * cos_x / d2
}

fn is_flat_lambert(set: &VplSet, i: usize) -> bool {
    set.lobe[i] == NO_LOBE && set.flags[i] & ON_LIGHT == 0
}

impl VplSampler for Bir {
    fn name(&self) -> &'static str {
        "bir"
    }

    fn sample(&mut self, scene: &Scene, accel: &Accel, camera: &Camera, m: usize, seed: u64) -> (VplSet, SamplerStats) {
        let t0 = Instant::now();
        let mut rays = RayStats::default();
        let probes = camera_probes(scene, accel, camera, self.probes, seed ^ 0xb1b1, &mut rays);
        let half = (self.resampling * m / 2).max(1);
        // Standard candidates.
        let (full, _) = self.sir.sample(scene, accel, camera, half, seed);
        let paths = full.groups.max(1);
        let mut standard = full.clone();
        // Partition weights for reflected-light standard VPLs: ½ where the reverse technique
        // could also have produced the location.
        if !probes.is_empty() {
            for i in 0..standard.len() {
                if !is_flat_lambert(&standard, i) {
                    continue;
                }
                let (p, n) = (standard.position[i], standard.normal[i]);
                if probes.iter().any(|r| probe_density(scene, accel, r, p, n, &mut rays) > 0.0) {
                    standard.radiance[i] *= 0.5;
                }
            }
        }
        // Reverse candidates.
        let mut candidates = standard.clone();
        let mut reverse_made = 0u64;
        if !probes.is_empty() && !full.is_empty() {
            let subset = self.gather_subset.min(full.len());
            for j in 0..half {
                let mut s = IndependentSampler::for_stream(seed, TAG_REVERSE, j as u64);
                let r = &probes[(s.next_1d() * probes.len() as f32) as usize % probes.len()];
                let w = Frame::from_normal(r.bsdf.frame.n).to_world(warp::sample_cosine_hemisphere(s.next_2d()));
                let o = offset_origin(&r.sp, &scene.mesh.corners(r.sp.tri), w);
                rays.closest += 1;
                let Some(hit) = accel.intersect(o, w, f32::INFINITY) else { continue };
                let sp = scene.surface_point(hit.tri, hit.b1, hit.b2);
                let bsdf = crate::bsdf::Bsdf::new(
                    scene.material_of(hit.tri).bsdf_kind(sp.uv, &scene.textures),
                    sp.ns,
                    sp.ng,
                    -w,
                );
                let BsdfKind::Lambert { albedo } = bsdf.kind else { continue };
                if (bsdf.frame.n - bsdf.ng).length_squared() > 1e-10 || albedo == Vec3::ZERO {
                    continue;
                }
                let p_e: f32 =
                    probes.iter().map(|q| probe_density(scene, accel, q, sp.p, bsdf.ng, &mut rays)).sum::<f32>()
                        / probes.len() as f32;
                if !(p_e > 0.0) {
                    continue;
                }
                // Irradiance at x₂ from a random subset of the standard VPLs (scaled up).
                let recv = Receiver { sp, bsdf, wo: bsdf.frame.n, beta: Vec3::ONE };
                let mut irr = Vec3::ZERO;
                for _ in 0..subset {
                    let v = (s.next_1d() * full.len() as f32) as usize % full.len();
                    // contribution() includes f = ρ/π at the receiver: this sums reflected radiance.
                    irr += contribution(scene, accel, &full, v, &recv, f32::INFINITY, &mut rays);
                }
                let lo = irr * (full.len() as f32 / subset as f32);
                if lo == Vec3::ZERO {
                    continue;
                }
                reverse_made += 1;
                candidates.push(Vpl {
                    position: sp.p,
                    normal: bsdf.frame.n,
                    radiance: lo * (0.5 / (p_e * half as f32)),
                    lobe: None,
                    count: 1,
                    flags: 0,
                    length: 1,
                    group: paths + j as u32,
                });
            }
        }
        // Importance of every candidate at the probes, and resampling.
        let phi: Vec<f64> = (0..candidates.len())
            .map(|i| {
                probes
                    .iter()
                    .map(|r| luminance(contribution(scene, accel, &candidates, i, r, f32::INFINITY, &mut rays)) as f64)
                    .sum()
            })
            .collect();
        let mean = phi.iter().sum::<f64>() / phi.len().max(1) as f64;
        let weights: Vec<f64> = phi.iter().map(|&p| p + 0.1 * mean.max(1e-30)).collect();
        let mut out = VplSet::default();
        if let Some(dist) = Distribution1D::new(&weights) {
            let total = dist.total();
            let mut s = IndependentSampler::for_stream(seed, TAG_RESAMPLE, 0);
            for k in 0..m {
                let pick = dist.sample(s.next_1d());
                let i = pick.index;
                let scale = (total / (m as f64 * weights[i])) as f32;
                out.push(Vpl {
                    position: candidates.position[i],
                    normal: candidates.normal[i],
                    radiance: candidates.radiance[i] * scale,
                    lobe: match candidates.lobe[i] {
                        NO_LOBE => None,
                        l => Some(candidates.lobes[l as usize]),
                    },
                    count: 1,
                    flags: candidates.flags[i],
                    length: candidates.length[i],
                    group: k as u32,
                });
            }
        }
        out.groups = m as u32;
        let stats = SamplerStats {
            time: t0.elapsed(),
            candidates: candidates.len() as u64,
            kept: out.len(),
            paths: paths as u64 + reverse_made,
            rays,
            ..Default::default()
        };
        (out, stats)
    }
}
