//! Standard instant radiosity (Keller 1997): light paths from lights chosen ∝ power (or by a
//! light-source CDF, Wald et al. 2003, see [`super::cdf`]), a VPL at every non-specular vertex,
//! Russian roulette ending the paths.
//!
//! For an unbiased estimate the number of light paths N must not depend on the paths themselves
//! (stopping "when m VPLs exist" would couple N to path lengths), so N is fixed in advance from a
//! pilot estimate of VPLs per path drawn from an independent stream: N = round(m / pilot mean).

use std::time::Instant;

use glam::Vec3;

use super::set::{ON_LIGHT, TWO_SIDED, Vpl, VplLobe, VplSet};
use super::{SamplerStats, VplSampler};
use crate::accel::Accel;
use crate::path::{Vertex, VertexKind, light_subpath_with};
use crate::sampling::{Distribution1D, IndependentSampler};
use crate::scene::{Camera, Light, Scene};
use crate::stats::RayStats;

/// Stream tag of light paths.
const TAG_PATHS: u64 = 0x5349_525f_5041_5448;
/// Stream tag of the pilot.
const TAG_PILOT: u64 = 0x5349_525f_5049_4c54;

/// The VPL at light sub-path vertex `v` (index `i` along the path), its radiance scaled by
/// `scale`; `None` for specular vertices (they cannot be connected to).
pub fn vpl_of_vertex(scene: &Scene, v: &Vertex, i: usize, scale: f32, group: u32) -> Option<Vpl> {
    match v.kind {
        VertexKind::Light => {
            if !(v.pdf_fwd > 0.0) {
                return None;
            }
            let inv_pdf = scale / v.pdf_fwd;
            if v.at_infinity {
                // The light arriving along the path's first direction, over that direction's
                // density over all lights at infinity (or the sun's choice).
                let e = if v.delta { v.beta } else { scene.escaped(v.ns) };
                return Some(directional_vpl(scene, v.ns, e * inv_pdf, group));
            }
            let (radiance, lobe, normal, flags) = match scene.lights.list[v.light as usize] {
                Light::Area { two_sided, .. } => {
                    (v.beta * inv_pdf, None, v.ng, ON_LIGHT | if two_sided { TWO_SIDED } else { 0 })
                }
                Light::Point { intensity, .. } => (intensity * inv_pdf, None, Vec3::ZERO, ON_LIGHT),
                Light::Spot { intensity, frame, cos_inner, cos_outer, .. } => (
                    intensity * inv_pdf,
                    Some(VplLobe::Spot { axis: frame.n, cos_inner, cos_outer }),
                    Vec3::ZERO,
                    ON_LIGHT,
                ),
                Light::Sun(_) | Light::Sky(_) => unreachable!("vertices at infinity return above"),
            };
            Some(Vpl { position: v.p, normal, radiance, lobe, count: 1, flags, length: 0, group })
        }
        VertexKind::Surface => {
            let bsdf = v.bsdf?;
            if bsdf.is_delta() {
                return None;
            }
            let beta = v.beta * scale;
            let flat = (bsdf.frame.n - bsdf.ng).length_squared() < 1e-10;
            let (radiance, lobe) = match bsdf.kind {
                crate::bsdf::BsdfKind::Lambert { albedo } if flat => {
                    (beta * albedo * std::f32::consts::FRAC_1_PI, None)
                }
                _ => (beta, Some(VplLobe::Surface { bsdf, wo: v.wo })),
            };
            Some(Vpl {
                position: v.p,
                normal: bsdf.frame.n,
                radiance,
                lobe,
                count: 1,
                flags: 0,
                length: i.min(255) as u8,
                group,
            })
        }
        VertexKind::Camera => None,
    }
}

/// How far, in bounding-sphere radii, a directional VPL sits from the scene's centre.
pub const DIRECTIONAL_DISTANCE: f32 = 1.0e5;

/// A VPL for light arriving from direction `wi` (towards the light) with irradiance `e` on a
/// surface facing it: a one-sided emitter facing the scene at [`DIRECTIONAL_DISTANCE`] radii
/// in that direction, its radiance scaled by the squared distance, so that every kernel of the
/// gather gives e·cos θ·f with no distance fall-off of its own (the 1/d² over the scene changes
/// by at most 2/[`DIRECTIONAL_DISTANCE`] of the value) and its G never reaches a clamp.
pub fn directional_vpl(scene: &Scene, wi: Vec3, e: Vec3, group: u32) -> Vpl {
    let (c, r) = scene.bounding_sphere();
    let d = DIRECTIONAL_DISTANCE * r;
    Vpl {
        position: c + wi * d,
        normal: -wi,
        radiance: e * (d * d),
        lobe: None,
        count: 1,
        flags: ON_LIGHT,
        length: 0,
        group,
    }
}

/// Appends the VPLs of one light sub-path (each scaled by `scale`) to `set`.
pub fn vpls_from_light_path(scene: &Scene, path: &[Vertex], scale: f32, group: u32, set: &mut VplSet) {
    for (i, v) in path.iter().enumerate() {
        if let Some(vpl) = vpl_of_vertex(scene, v, i, scale, group) {
            set.push(vpl);
        }
    }
}

/// Number of VPLs a light sub-path yields.
fn vpl_count(path: &[Vertex]) -> usize {
    path.iter().filter(|v| v.kind == VertexKind::Light || v.bsdf.is_some_and(|b| !b.is_delta())).count()
}

/// The SIR sampler; holds the pilot estimate and, for SIR+CDF, the light distribution.
#[derive(Debug, Default)]
pub struct Sir {
    /// Maximum number of light-path vertices (scattering events of the full path − 1).
    pub max_vertices: usize,
    /// Light-source CDF, when set (SIR+CDF).
    pub light_cdf: Option<Distribution1D>,
    vpls_per_path: Option<f64>,
}

impl Sir {
    /// SIR with lights chosen ∝ power; light sub-paths of at most `max_depth` vertices.
    pub fn new(max_depth: u32) -> Self {
        Sir { max_vertices: max_depth.max(1) as usize, light_cdf: None, vpls_per_path: None }
    }

    /// Chooses lights with `dist` from now on (SIR+CDF); forgets the pilot estimate.
    pub fn set_light_cdf(&mut self, dist: Option<Distribution1D>) {
        self.light_cdf = dist;
        self.vpls_per_path = None;
    }

    /// Traces `n` light paths and returns their VPLs, each path a group, scaled by 1/n.
    pub fn trace(&self, scene: &Scene, accel: &Accel, n: usize, seed: u64, stats: &mut RayStats) -> VplSet {
        let dist = self.light_cdf.as_ref().unwrap_or(&scene.lights.distribution);
        let mut set = VplSet::default();
        let mut path = Vec::with_capacity(16);
        for p in 0..n {
            let mut sampler = IndependentSampler::for_stream(seed, TAG_PATHS, p as u64);
            light_subpath_with(scene, accel, dist, &mut sampler, self.max_vertices, &mut path, stats);
            vpls_from_light_path(scene, &path, 1.0 / n as f32, p as u32, &mut set);
        }
        set.groups = n as u32;
        set
    }

    /// Mean number of VPLs per light path (pilot of 256 paths on an independent stream).
    fn vpls_per_path(&mut self, scene: &Scene, accel: &Accel, stats: &mut RayStats) -> f64 {
        if let Some(v) = self.vpls_per_path {
            return v;
        }
        let dist = self.light_cdf.as_ref().unwrap_or(&scene.lights.distribution);
        let mut path = Vec::new();
        let pilot = 256;
        let mut total = 0usize;
        for p in 0..pilot {
            let mut sampler = IndependentSampler::for_stream(0, TAG_PILOT, p);
            light_subpath_with(scene, accel, dist, &mut sampler, self.max_vertices, &mut path, stats);
            total += vpl_count(&path);
        }
        let v = (total as f64 / pilot as f64).max(1.0);
        self.vpls_per_path = Some(v);
        v
    }
}

impl VplSampler for Sir {
    fn name(&self) -> &'static str {
        if self.light_cdf.is_some() { "sir-cdf" } else { "sir" }
    }

    fn sample(
        &mut self,
        scene: &Scene,
        accel: &Accel,
        _camera: &Camera,
        m: usize,
        seed: u64,
    ) -> (VplSet, SamplerStats) {
        let t0 = Instant::now();
        let mut rays = RayStats::default();
        let per_path = self.vpls_per_path(scene, accel, &mut rays);
        let n = ((m as f64 / per_path).round() as usize).max(1);
        let set = self.trace(scene, accel, n, seed, &mut rays);
        let stats = SamplerStats {
            time: t0.elapsed(),
            candidates: n as u64,
            kept: set.len(),
            paths: n as u64,
            rays,
            ..Default::default()
        };
        (set, stats)
    }
}
