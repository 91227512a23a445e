//! The light-source CDF of Wald, Benthin & Slusallek 2003: lights chosen ∝ their estimated
//! contribution to the image instead of ∝ their power.
//!
//! Pilot pass: light paths (lights chosen ∝ power) whose vertices are connected to a few
//! camera-visible points; each light's share of the image is estimated from its paths. Every
//! light keeps a floor of probability (a fraction of its power share), so no light that might
//! contribute is ever excluded and SIR with this CDF stays unbiased.

use std::time::Instant;

use glam::{Vec2, vec2};

use super::set::VplSet;
use super::sir::{Sir, vpls_from_light_path};
use super::transfer::{Receiver, contribution, primary_receiver};
use super::{SamplerStats, VplSampler};
use crate::accel::Accel;
use crate::color::luminance;
use crate::path::light_subpath;
use crate::sampling::{Distribution1D, IndependentSampler, Sampler};
use crate::scene::{Camera, Scene};
use crate::stats::RayStats;

const TAG_CAMERA: u64 = 0x0043_4446_5f43_414d;
const TAG_LIGHT: u64 = 0x0043_4446_5f4c_4947;

/// Camera-visible receivers at `k` random image positions (the probes of pilot passes).
pub fn camera_probes(
    scene: &Scene,
    accel: &Accel,
    camera: &Camera,
    k: usize,
    seed: u64,
    stats: &mut RayStats,
) -> Vec<Receiver> {
    let mut out = Vec::with_capacity(k);
    for i in 0..k {
        let mut s = IndependentSampler::for_stream(seed, TAG_CAMERA, i as u64);
        let raster = vec2(s.next_1d() * camera.width as f32, s.next_1d() * camera.height as f32);
        let lens: Vec2 = s.next_2d();
        let (r, _) = primary_receiver(scene, accel, camera, raster, lens, &mut || s.next_1d(), 4, stats);
        if let Some(r) = r {
            out.push(r);
        }
    }
    out
}

/// Estimates each light's contribution to the image with `paths` pilot light paths connected
/// to `probes` camera points, and returns the CDF ∝ max(estimate, floor · power share).
pub fn light_cdf(
    scene: &Scene,
    accel: &Accel,
    camera: &Camera,
    paths: usize,
    probes: usize,
    max_vertices: usize,
    seed: u64,
    stats: &mut RayStats,
) -> Distribution1D {
    let receivers = camera_probes(scene, accel, camera, probes, seed, stats);
    let nl = scene.lights.list.len();
    let mut estimate = vec![0.0f64; nl];
    let mut path = Vec::new();
    for p in 0..paths {
        let mut s = IndependentSampler::for_stream(seed, TAG_LIGHT, p as u64);
        light_subpath(scene, accel, &mut s, max_vertices, &mut path, stats);
        let Some(first) = path.first() else { continue };
        let light = first.light as usize;
        let mut set = VplSet::default();
        vpls_from_light_path(scene, &path, 1.0 / paths as f32, 0, &mut set);
        let mut c = 0.0f64;
        for i in 0..set.len() {
            for r in &receivers {
                c += luminance(contribution(scene, accel, &set, i, r, f32::INFINITY, stats)) as f64;
            }
        }
        estimate[light] += c;
    }
    let total_est: f64 = estimate.iter().sum();
    let total_power: f64 = scene.lights.power.iter().map(|p| luminance(*p) as f64).sum();
    // Floor: 5 % of the estimated image power spread over lights by their power share.
    let weights: Vec<f64> = (0..nl)
        .map(|l| {
            let share = luminance(scene.lights.power[l]) as f64 / total_power.max(1e-300);
            estimate[l].max(0.05 * total_est * share).max(1e-12 * share)
        })
        .collect();
    Distribution1D::new(&weights).unwrap_or_else(|| scene.lights.distribution.clone())
}

/// SIR with lights chosen by [`light_cdf`], recomputed whenever the camera changes.
#[derive(Debug)]
pub struct SirCdf {
    /// The SIR sampler the CDF is installed in.
    pub sir: Sir,
    /// Pilot light paths.
    pub pilot_paths: usize,
    /// Camera probes of the pilot.
    pub probes: usize,
    camera: Option<Camera>,
}

impl SirCdf {
    /// SIR+CDF with a pilot of 1024 light paths and 32 camera probes.
    pub fn new(max_depth: u32) -> Self {
        SirCdf { sir: Sir::new(max_depth), pilot_paths: 1024, probes: 32, camera: None }
    }
}

impl VplSampler for SirCdf {
    fn name(&self) -> &'static str {
        "sir-cdf"
    }

    fn reset(&mut self) {
        self.camera = None;
    }

    fn sample(&mut self, scene: &Scene, accel: &Accel, camera: &Camera, m: usize, seed: u64) -> (VplSet, SamplerStats) {
        let t0 = Instant::now();
        let mut rays = RayStats::default();
        if self.camera.as_ref() != Some(camera) {
            let max_vertices = self.sir.max_vertices;
            let dist = light_cdf(scene, accel, camera, self.pilot_paths, self.probes, max_vertices, 0x0cdf, &mut rays);
            self.sir.set_light_cdf(Some(dist));
            self.camera = Some(camera.clone());
        }
        let (set, mut stats) = self.sir.sample(scene, accel, camera, m, seed);
        stats.rays += rays;
        stats.time = t0.elapsed();
        (set, stats)
    }
}
