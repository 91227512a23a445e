//! Complete paths for Metropolis instant radiosity (papers/002 §4.4, §5.2): the camera end
//! `x̄_c = (x₀, x₁)` (a lens point and the first surface it sees), and a light sub-path
//! `y₀ … y_{s−1}` whose last vertex is the VPL location `x_v`, connected to `x₁`.
//!
//! The contribution of a path is computed with the gather's own kernel
//! ([`super::transfer::unshadowed`]) applied to the VPL that `x_v` would be, so the chain's
//! target and the image the gather makes from its VPLs agree by construction.

use glam::{Vec2, Vec3};

use super::set::Vpl;
use super::sir::vpl_of_vertex;
use super::transfer::{Receiver, SHADOW_T_MAX, unshadowed_vpl};
use crate::accel::{Accel, offset_origin, ray_offset};
use crate::bsdf::{Bsdf, TransportMode};
use crate::color::luminance;
use crate::path::{Vertex, VertexKind, shading_correction};
use crate::sampling::{Distribution1D, Sampler};
use crate::scene::{Camera, Scene};
use crate::stats::RayStats;

/// The camera end of a path: lens vertex x₀, first surface x₁ (never specular).
#[derive(Clone, Copy, Debug)]
pub struct CameraEnd {
    /// The x₁ receiver (surface point, BSDF, direction to the camera).
    pub receiver: Receiver,
    /// Log of the density of (x₀, x₁): lens position × area density of x₁.
    pub log_pdf: f64,
}

/// Traces the camera ray through `raster` (lens sample `lens`) to x₁; `None` when it misses or
/// lands on a specular surface (such paths are not in MIR's domain).
pub fn camera_end(
    scene: &Scene,
    accel: &Accel,
    camera: &Camera,
    raster: Vec2,
    lens: Vec2,
    stats: &mut RayStats,
) -> Option<CameraEnd> {
    let ray = camera.generate_ray(raster, lens);
    let (pdf_pos, pdf_dir) = camera.pdf_we(ray.dir);
    stats.closest += 1;
    let hit = accel.intersect(ray.origin, ray.dir, f32::INFINITY)?;
    let sp = scene.surface_point(hit.tri, hit.b1, hit.b2);
    let wo = -ray.dir;
    let bsdf = Bsdf::new(scene.material_of(hit.tri).bsdf_kind(sp.uv, &scene.textures), sp.ns, sp.ng, wo);
    if bsdf.is_delta() {
        return None;
    }
    let d2 = (sp.p - ray.origin).length_squared();
    let pdf_a = pdf_dir * sp.ng.dot(wo).abs() / d2;
    if !(pdf_a > 0.0 && pdf_pos > 0.0) {
        return None;
    }
    Some(CameraEnd {
        receiver: Receiver { sp, bsdf, wo, beta: Vec3::ONE },
        log_pdf: (pdf_pos as f64).ln() + (pdf_a as f64).ln(),
    })
}

/// The VPL that light vertex `light[i]` is (unit scale), if it can be connected to.
pub fn vertex_vpl(scene: &Scene, light: &[Vertex], i: usize) -> Option<Vpl> {
    vpl_of_vertex(scene, &light[i], i, 1.0, 0)
}

/// Bound on the geometry term of the VPL–x₁ connection in the chains' target, in the units of
/// `--clamp` (see [`crate::vpl::transfer::g_bound`]). The target only decides where VPLs go and
/// how the counts are normalised: the probes that measure P′ use the same bound, so a VPL's
/// radiance P_i/P′_i is the same ratio of two quantities of one kernel and the image stays
/// unbiased (the bound never turns a positive target into zero). Without it a chain that
/// reaches a VPL a hair away from x₁ (G ∝ 1/d²) rejects every proposal for thousands of steps
/// and that one location takes a huge count: measured on the Cornell box, 256 VPLs, one frame
/// in ~50 had a VPL of count 1475 and ruined the running mean (relMSE 0.0035 → 0.17).
/// The bound was 1000 until a continued chain sat in a floor corner for 8 frames (counts up to
/// 872 of ~1300 states; still camera, relMSE 0.0034 → 0.088 between 32 and 64 frames): at 100
/// the largest count in 64 frames is ~120, and the 64-frame relMSE over 10 seeds has median
/// 0.0012 and worst 0.0027 (1000: 0.0021 and 0.088). On ajar-door (5 frames, 20 seeds) the
/// bound changes nothing beyond the seed-to-seed spread.
///
/// The bound also means the chains hardly visit VPLs right next to the surfaces they light
/// (their clamped response is tiny): behind a slit in a thick wall that is 30 % of the image
/// (issue 19). An unclamped gather recovers that light only through those VPLs' huge
/// P_i/P′_i, a tail a render of seconds does not sample; the gather therefore clamps at a
/// bound ≥ this one and compensates the clamp ([`crate::frame::FrameSettings::compensated`]).
pub const TARGET_CLAMP: f32 = 100.0;

/// The geometry-term bound of the chains' target in `scene` ([`TARGET_CLAMP`]).
pub fn target_g_bound(scene: &Scene) -> f32 {
    crate::vpl::transfer::g_bound(scene, TARGET_CLAMP)
}

/// Unweighted contribution `C* = f / p` of the path (camera end, light sub-path prefix ending at
/// `vpl`): radiance arriving at the camera through x₁ with the x₁–VPL geometry term bounded at
/// [`target_g_bound`], zero when occluded.
pub fn contribution(scene: &Scene, accel: &Accel, cam: &CameraEnd, vpl: &Vpl, stats: &mut RayStats) -> Vec3 {
    let Some((c, _)) = unshadowed_vpl(vpl, &cam.receiver, target_g_bound(scene)) else { return Vec3::ZERO };
    let r = &cam.receiver;
    let origin = offset_origin(&r.sp, &scene.mesh.corners(r.sp.tri), vpl.position - r.sp.p);
    stats.shadow += 1;
    if accel.occluded(origin, vpl.position - origin, SHADOW_T_MAX) { Vec3::ZERO } else { c }
}

/// Luminance of a contribution, the scalar target of the chains (docs/design.md §2).
#[inline]
pub fn target(c: Vec3) -> f64 {
    luminance(c).max(0.0) as f64
}

/// Extends a light sub-path by exactly `k` vertices (no Russian roulette): from nothing, a
/// light is chosen with `dist`, then every new vertex is sampled from the last one (emission or
/// BSDF sampling). Every vertex keeps its forward density in area measure (a discrete
/// probability for specular events). Returns false when the walk leaves the scene or is
/// absorbed before `k` vertices exist.
pub fn extend_light(
    scene: &Scene,
    accel: &Accel,
    dist: &Distribution1D,
    light: &mut Vec<Vertex>,
    k: usize,
    sampler: &mut impl Sampler,
    stats: &mut RayStats,
) -> bool {
    let target_len = light.len() + k;
    if light.is_empty() {
        let u_light = sampler.next_1d();
        let u_pos = sampler.next_2d();
        let u_dir = sampler.next_2d();
        let Some(es) = scene.sample_le_with(dist, u_light, u_pos, u_dir) else { return false };
        if !(es.pdf_pos > 0.0) {
            return false;
        }
        if es.at_infinity {
            // A light at infinity: the first vertex is a direction (the disk point is drawn
            // with the next vertex). Its density is the direction's over all the lights a
            // ray meets there (the choice alone for a delta sun), and it carries their
            // radiance together, as the directional VPL it is ([`vpl_of_vertex`]).
            let wi = -es.dir;
            let delta = scene.lights.list[es.light as usize].is_delta();
            let (pdf, le) = if delta {
                (dist.pmf(es.light as usize), es.le)
            } else {
                (scene.pdf_li_escaped_with(dist, wi), scene.escaped(wi))
            };
            if !(pdf > 0.0) {
                return false;
            }
            let mut v = Vertex::at_infinity(es.light, scene.far_point(scene.bounding_sphere().0, wi), wi, le, pdf);
            v.delta = delta;
            light.push(v);
        } else {
            let le = match scene.lights.list[es.light as usize] {
                crate::scene::Light::Spot { intensity, .. } => intensity,
                _ => es.le,
            };
            let mut v = Vertex::light(scene, es.light, es.p, es.n, le, es.pdf_pos);
            v.delta = es.delta_pos;
            light.push(v);
        }
    }
    while light.len() < target_len {
        let last = *light.last().expect("non-empty");
        let u_lobe = sampler.next_1d();
        let u = sampler.next_2d();
        let (origin, dir, pdf_w, weight) = match last.kind {
            // From infinity: a point on the bounding sphere's disk facing the direction (area
            // density 1/(πR²); the next vertex's is that times its cosine).
            _ if last.at_infinity => {
                let (c, r) = scene.bounding_sphere();
                let frame = crate::bsdf::Frame::from_normal(last.ns);
                let d = crate::sampling::warp::sample_uniform_disk_concentric(u) * r;
                let origin = c + last.ns * r + frame.to_world(Vec3::new(d.x, d.y, 0.0));
                let disk = 1.0 / (std::f32::consts::PI * r * r);
                (origin, -last.ns, disk, last.beta / (last.pdf_fwd * disk))
            }
            VertexKind::Light => {
                let Some((dir, pdf_dir, falloff)) = scene.sample_light_direction(last.light, last.ng, u) else {
                    return false;
                };
                if !(pdf_dir > 0.0) || falloff <= 0.0 {
                    return false;
                }
                let cos = if last.ng == Vec3::ZERO { 1.0 } else { last.ng.dot(dir).abs() };
                let origin = if last.ng == Vec3::ZERO {
                    last.p
                } else {
                    let d = ray_offset(last.p, &scene.mesh.corners(last.tri));
                    if last.ng.dot(dir) >= 0.0 { last.p + last.ng * d } else { last.p - last.ng * d }
                };
                (origin, dir, pdf_dir, last.beta * (cos * falloff / (last.pdf_fwd * pdf_dir)))
            }
            VertexKind::Surface => {
                let Some(bsdf) = last.bsdf else { return false };
                let Some(bs) = bsdf.sample(last.wo, u_lobe, u, TransportMode::Importance) else { return false };
                let w = bs.f * (bsdf.abs_cos(bs.wi) / bs.pdf_w) * shading_correction(&bsdf, last.wo, bs.wi);
                let sp = scene.surface_point(last.tri, 0.0, 0.0);
                let sp = crate::scene::SurfacePoint { p: last.p, ng: last.ng, ..sp };
                let origin = offset_origin(&sp, &scene.mesh.corners(last.tri), bs.wi);
                (origin, bs.wi, bs.pdf_w, last.beta * w)
            }
            VertexKind::Camera => return false,
        };
        if weight == Vec3::ZERO || !weight.is_finite() {
            return false;
        }
        stats.closest += 1;
        let Some(hit) = accel.intersect(origin, dir, f32::INFINITY) else { return false };
        let sp = scene.surface_point(hit.tri, hit.b1, hit.b2);
        let wo = -dir;
        let bsdf = Bsdf::new(scene.material_of(hit.tri).bsdf_kind(sp.uv, &scene.textures), sp.ns, sp.ng, wo);
        let mut v = Vertex {
            kind: VertexKind::Surface,
            p: sp.p,
            ng: sp.ng,
            ns: bsdf.frame.n,
            uv: sp.uv,
            tri: hit.tri,
            light: scene.mesh.emitter[hit.tri as usize],
            wo,
            bsdf: Some(bsdf),
            beta: weight,
            delta: bsdf.is_delta(),
            pdf_fwd: 0.0,
            pdf_rev: 0.0,
            at_infinity: false,
        };
        v.pdf_fwd = if last.at_infinity { pdf_w * v.ng.dot(dir).abs() } else { last.convert_density(pdf_w, &v) };
        if !(v.pdf_fwd > 0.0) || !v.pdf_fwd.is_finite() {
            return false;
        }
        light.push(v);
    }
    true
}

/// Σ ln pdf_fwd of `light[from..to]`.
pub fn log_pdf_range(light: &[Vertex], from: usize, to: usize) -> f64 {
    light[from..to].iter().map(|v| (v.pdf_fwd as f64).ln()).sum()
}
