//! Connecting a light sub-path prefix of `s` vertices with a camera sub-path prefix of `t`
//! vertices, and the multiple-importance weight of that strategy (Veach 1997 §10.2–10.3;
//! papers/000 eq. 18 and Appendix A: `C*_{s,t} = α^L_s c_{s,t} α^E_t`, weighted by the power
//! heuristic `w_{s,t} = p²_{s,t} / Σ_i p²_i`).
//!
//! Strategies: `s = 0` (the camera path hits an emitter), `s = 1` (next-event estimation: a new
//! light point is sampled), `t = 1` (light tracing: a new lens point is sampled and the result is
//! splatted to the pixel the connection projects to), and `s, t ≥ 2` (a deterministic
//! connection). The weights are computed from the densities cached on the vertices as ratios
//! `p_i / p_{s,t}` walking away from the connection, so no strategy is ever evaluated twice.

use glam::{Vec2, Vec3};

use super::vertex::{Vertex, geometry};
use crate::accel::{Accel, ray_offset};
use crate::bsdf::TransportMode;
use crate::sampling::Sampler;
use crate::scene::Scene;
use crate::stats::RayStats;

/// The result of one (s, t) connection.
#[derive(Clone, Copy, Debug, Default)]
pub struct Connection {
    /// Unweighted contribution `C*_{s,t}` (radiance, or pixel measurement for splats).
    pub unweighted: Vec3,
    /// MIS weight `w_{s,t}`.
    pub weight: f32,
    /// For t = 1: the raster position to splat to.
    pub raster: Option<Vec2>,
}

impl Connection {
    /// `w_{s,t} C*_{s,t}`.
    pub fn weighted(&self) -> Vec3 {
        self.unweighted * self.weight
    }
}

/// A point just off a vertex's surface towards `target` (for shadow rays).
fn lift(scene: &Scene, v: &Vertex, target: Vec3) -> Vec3 {
    if v.tri == crate::path::vertex::NO_TRI || v.ng == Vec3::ZERO {
        return v.p;
    }
    let d = ray_offset(v.p, &scene.mesh.corners(v.tri));
    if v.ng.dot(target - v.p) >= 0.0 { v.p + v.ng * d } else { v.p - v.ng * d }
}

/// True when nothing blocks the segment between two vertices.
pub fn unoccluded(scene: &Scene, accel: &Accel, a: &Vertex, b: &Vertex, stats: &mut RayStats) -> bool {
    let oa = lift(scene, a, b.p);
    let ob = lift(scene, b, a.p);
    stats.shadow += 1;
    !accel.occluded(oa, ob - oa, 1.0 - 1e-4)
}

/// Evaluates strategy (s, t) for the given sub-paths (`light.len() ≥ s`, `camera.len() ≥ t`).
/// Strategies s = 1 and t = 1 draw fresh samples from `sampler`.
pub fn connect(
    scene: &Scene,
    accel: &Accel,
    light: &[Vertex],
    camera: &[Vertex],
    s: usize,
    t: usize,
    sampler: &mut impl Sampler,
    stats: &mut RayStats,
) -> Connection {
    let none = Connection::default();
    if t == 0 {
        // The camera cannot be hit by a light path (pinhole / thin lens are not in the scene).
        return none;
    }
    let mut sampled: Option<Vertex> = None;
    let mut raster = None;
    let l;
    if s == 0 {
        let pt = &camera[t - 1];
        if t < 2 || !pt.is_light() {
            return none;
        }
        l = pt.beta * pt.le(scene, &camera[t - 2]);
    } else if t == 1 {
        let qs = &light[s - 1];
        if !qs.connectible() {
            return none;
        }
        let u = sampler.next_2d();
        let Some(cs) = scene.camera.sample_wi(lift(scene, qs, scene.camera.position), u) else { return none };
        if cs.pdf_w <= 0.0 || cs.we <= 0.0 {
            return none;
        }
        let (pdf_pos, _) = scene.camera.pdf_we(-cs.wi);
        let cam = Vertex::camera(cs.p_lens, scene.camera.forward, Vec3::splat(cs.we / cs.pdf_w), pdf_pos);
        let mut c = qs.beta * qs.f(&cam, TransportMode::Importance) * cam.beta;
        if qs.on_surface() {
            c *= cs.wi.dot(qs.ns).abs();
        }
        if c == Vec3::ZERO || !unoccluded(scene, accel, qs, &cam, stats) {
            return none;
        }
        raster = Some(cs.raster);
        sampled = Some(cam);
        l = c;
    } else if s == 1 {
        let pt = &camera[t - 1];
        if !pt.connectible() {
            return none;
        }
        let u_light = sampler.next_1d();
        let u = sampler.next_2d();
        let Some(ls) = scene.sample_li(pt.p, u_light, u) else { return none };
        if ls.pdf_w <= 0.0 || ls.li == Vec3::ZERO {
            return none;
        }
        // Radiance (or intensity / d², or a delta sun's irradiance) arriving per unit
        // solid-angle density.
        let beta = ls.li / ls.pdf_w;
        let mut lv = if scene.lights.list[ls.light as usize].at_infinity() {
            Vertex::at_infinity(ls.light, ls.p, ls.wi, beta, 0.0)
        } else {
            Vertex::light(scene, ls.light, ls.p, ls.n, beta, 0.0)
        };
        lv.delta = ls.delta;
        lv.pdf_fwd = lv.pdf_light_origin(scene);
        let mut c = pt.beta * pt.f(&lv, TransportMode::Radiance) * lv.beta;
        if pt.on_surface() {
            c *= ls.wi.dot(pt.ns).abs();
        }
        if c == Vec3::ZERO || !unoccluded(scene, accel, pt, &lv, stats) {
            return none;
        }
        sampled = Some(lv);
        l = c;
    } else {
        let qs = &light[s - 1];
        let pt = &camera[t - 1];
        if !qs.connectible() || !pt.connectible() {
            return none;
        }
        let c = qs.beta * qs.f(pt, TransportMode::Importance) * pt.f(qs, TransportMode::Radiance) * pt.beta;
        if c == Vec3::ZERO {
            return none;
        }
        let c = c * geometry(qs, pt);
        if c == Vec3::ZERO || !unoccluded(scene, accel, qs, pt, stats) {
            return none;
        }
        l = c;
    }
    if l == Vec3::ZERO || !l.is_finite() {
        return none;
    }
    let weight = mis_weight(scene, light, camera, sampled.as_ref(), s, t);
    Connection { unweighted: l, weight, raster }
}

#[inline]
fn remap0(x: f32) -> f32 {
    if x != 0.0 { x } else { 1.0 }
}

/// Power-heuristic weight of strategy (s, t) (Veach 1997 eq. 10.9 with β = 2), from the cached
/// densities with the connection vertices' reverse densities updated for this strategy.
/// `sampled` is the vertex strategies s = 1 / t = 1 created in place of light[0] / camera[0].
pub fn mis_weight(
    scene: &Scene,
    light: &[Vertex],
    camera: &[Vertex],
    sampled: Option<&Vertex>,
    s: usize,
    t: usize,
) -> f32 {
    if s + t == 2 {
        return 1.0;
    }
    // The vertices as this strategy sees them: the sampled vertex replaces light[0] (s = 1) or
    // camera[0] (t = 1); connection vertices are never delta events; four reverse densities
    // change (those at and next to the connection). Everything else is read from the slices.
    let light_at = |i: usize| if s == 1 && i == 0 { sampled.copied().unwrap_or(light[0]) } else { light[i] };
    let camera_at = |i: usize| if t == 1 && i == 0 { sampled.copied().unwrap_or(camera[0]) } else { camera[i] };
    let qs = (s > 0).then(|| light_at(s - 1));
    let qs_minus = (s > 1).then(|| light_at(s - 2));
    let pt = camera_at(t - 1);
    let pt_minus = (t > 1).then(|| camera_at(t - 2));
    let pt_rev = match &qs {
        Some(q) => q.pdf(scene, qs_minus.as_ref(), &pt),
        None => pt.pdf_light_origin(scene),
    };
    let pt_minus_rev = pt_minus.map(|pm| match &qs {
        Some(q) => pt.pdf(scene, Some(q), &pm),
        None => pt.pdf_light(scene, &pm),
    });
    let qs_rev = qs.map(|q| pt.pdf(scene, pt_minus.as_ref(), &q));
    let qs_minus_rev = qs_minus.map(|qm| qs.expect("s > 1").pdf(scene, Some(&pt), &qm));

    let cam_rev = |i: usize| {
        if i == t - 1 {
            pt_rev
        } else if t > 1 && i == t - 2 {
            pt_minus_rev.unwrap_or(0.0)
        } else {
            camera[i].pdf_rev
        }
    };
    let cam_delta = |i: usize| i != t - 1 && camera_at(i).delta;
    let light_rev = |i: usize| {
        if i == s - 1 {
            qs_rev.unwrap_or(0.0)
        } else if s > 1 && i == s - 2 {
            qs_minus_rev.unwrap_or(0.0)
        } else {
            light[i].pdf_rev
        }
    };
    // A light sub-path's first vertex is never a scattering event: a point, spot or delta-sun
    // light there rules out only the strategy that would hit it (s = 0, `is_delta_light`
    // below), not next-event estimation (s = 1) as its `delta` flag would (pbrt-v3 §16.3.4
    // keeps the flag off on light vertices). Counting that flag dropped p₁ from every longer
    // strategy's weight: the weights then summed to more than one and bdpt under a delta sun
    // came out at twice the analytic value (tests/sky.rs).
    let light_delta = |i: usize| i != s - 1 && i > 0 && light_at(i).delta;

    let mut sum = 0.0f32;
    // Strategies that move the connection towards the camera (fewer camera vertices).
    let mut r = 1.0f32;
    for i in (1..t).rev() {
        r *= remap0(cam_rev(i)) / remap0(camera_at(i).pdf_fwd);
        if !cam_delta(i) && !cam_delta(i - 1) {
            sum += r * r;
        }
    }
    // Strategies that move it towards the light.
    let mut r = 1.0f32;
    for i in (0..s).rev() {
        r *= remap0(light_rev(i)) / remap0(light_at(i).pdf_fwd);
        let prev_delta = if i > 0 { light_delta(i - 1) } else { light_at(0).is_delta_light() };
        if !light_delta(i) && !prev_delta {
            sum += r * r;
        }
    }
    let w = 1.0 / (1.0 + sum);
    if w.is_finite() { w } else { 0.0 }
}
