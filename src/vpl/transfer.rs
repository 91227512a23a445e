//! How much a VPL gives a receiving point: `L_v · f_s · G · V` (papers/002 §4.4; docs/design.md §4),
//! the kernel shared by the gather, BIR's power estimates and MIR's normalisation.

use glam::Vec3;

use super::set::{Vpl, VplSet};
use crate::accel::{Accel, offset_origin};
use crate::bsdf::Bsdf;
use crate::scene::{Camera, Scene, SurfacePoint};
use crate::stats::RayStats;

/// A camera-visible surface point ready to receive light (a G-buffer entry).
#[derive(Clone, Copy, Debug)]
pub struct Receiver {
    /// The surface point.
    pub sp: SurfacePoint,
    /// Its BSDF, oriented towards the viewer.
    pub bsdf: Bsdf,
    /// Direction towards the viewer.
    pub wo: Vec3,
    /// Throughput from the camera (1, or the product of specular bounces).
    pub beta: Vec3,
}

/// Bound on G for `--clamp c`: `c / D²` with D the diagonal of the scene bounds, so the clamp
/// means the same at every scene scale; `c = 0` disables clamping.
pub fn g_bound(scene: &Scene, clamp: f32) -> f32 {
    if clamp <= 0.0 {
        return f32::INFINITY;
    }
    let d = scene.bounds.diagonal().max(1e-30);
    clamp / (d * d)
}

/// The unoccluded contribution of VPL `i` to receiver `r`: returns (clamped, unclamped)
/// radiance towards the viewer, before visibility; `None` when it is zero.
#[inline]
pub fn unshadowed(set: &VplSet, i: usize, r: &Receiver, g_max: f32) -> Option<(Vec3, Vec3)> {
    unshadowed_from(set.position[i], |w| set.cos_at(i, w), |w| set.radiance(i, w), r, g_max)
}

/// [`unshadowed`] for one VPL outside a set (no set to build for it).
#[inline]
pub fn unshadowed_vpl(v: &Vpl, r: &Receiver, g_max: f32) -> Option<(Vec3, Vec3)> {
    unshadowed_from(v.position, |w| v.cos_at(w), |w| v.radiance_towards(w), r, g_max)
}

#[inline(always)]
fn unshadowed_from(
    position: Vec3,
    cos_at: impl Fn(Vec3) -> f32,
    radiance: impl Fn(Vec3) -> Vec3,
    r: &Receiver,
    g_max: f32,
) -> Option<(Vec3, Vec3)> {
    let d = position - r.sp.p;
    let d2 = d.length_squared();
    if !(d2 > 0.0) {
        return None;
    }
    let dist = d2.sqrt();
    let wi = d / dist;
    let cos_v = cos_at(-wi);
    if cos_v <= 0.0 {
        return None;
    }
    let cos_r = r.bsdf.abs_cos(wi);
    let f = r.bsdf.f(r.wo, wi);
    if f == Vec3::ZERO {
        return None;
    }
    let le = radiance(-wi);
    if le == Vec3::ZERO {
        // The VPL sends nothing this way (its lobe's far side): no contribution, no shadow ray.
        return None;
    }
    let g = cos_v * cos_r / d2;
    let base = r.beta * le * f;
    Some((base * g.min(g_max), base * g))
}

/// The shadow-ray segment from a receiver to VPL `i` (origin offset off the surface, end
/// stopping short of the VPL's own surface).
#[inline]
pub fn shadow_segment(scene: &Scene, set: &VplSet, i: usize, r: &Receiver) -> (Vec3, Vec3) {
    let target = set.position[i];
    let origin = offset_origin(&r.sp, &scene.mesh.corners(r.sp.tri), target - r.sp.p);
    (origin, target - origin)
}

/// Fraction of a shadow segment that is tested (the VPL's own surface is not an occluder): the
/// one constant of [`crate::accel`], re-exported beside the segment builders.
pub use crate::accel::SHADOW_T_MAX;

/// Contribution of VPL `i` to `r` with visibility, clamped at `g_max` (single rays).
pub fn contribution(
    scene: &Scene,
    accel: &Accel,
    set: &VplSet,
    i: usize,
    r: &Receiver,
    g_max: f32,
    stats: &mut RayStats,
) -> Vec3 {
    let Some((c, _)) = unshadowed(set, i, r, g_max) else { return Vec3::ZERO };
    let (o, d) = shadow_segment(scene, set, i, r);
    stats.shadow += 1;
    if accel.occluded(o, d, SHADOW_T_MAX) { Vec3::ZERO } else { c }
}

/// Traces the camera ray through `raster` to the first non-specular surface (following up to
/// `max_specular` mirror / glass bounces); returns the receiver and the emission seen on the way.
pub fn primary_receiver(
    scene: &Scene,
    accel: &Accel,
    camera: &Camera,
    raster: glam::Vec2,
    u_lens: glam::Vec2,
    u_specular: &mut impl FnMut() -> f32,
    max_specular: u32,
    stats: &mut RayStats,
) -> (Option<Receiver>, Vec3) {
    let ray = camera.generate_ray(raster, u_lens);
    stats.closest += 1;
    let first = accel.intersect(ray.origin, ray.dir, f32::INFINITY);
    receiver_from_hit(scene, accel, ray, first, u_specular, max_specular, stats)
}

/// [`primary_receiver`] continued from the camera ray `ray` whose closest hit `first` is already
/// known (traced in a packet by the G-buffer), with the same specular bounces.
#[inline]
pub fn receiver_from_hit(
    scene: &Scene,
    accel: &Accel,
    ray: crate::scene::Ray,
    first: Option<crate::accel::Hit>,
    u_specular: &mut impl FnMut() -> f32,
    max_specular: u32,
    stats: &mut RayStats,
) -> (Option<Receiver>, Vec3) {
    receiver_with(scene, accel, ray, first, u_specular, max_specular, stats, |r, e| (r.copied(), e))
}

/// [`receiver_from_hit`] handing the receiver and the emission seen on the way to `sink` where
/// they are found. (Returned by value, the receiver was copied out of the bounce loop's exits
/// into a temporary right after its fields were stored, and every copy stalled on those stores:
/// a quarter of the G-buffer's time.)
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn receiver_with<T>(
    scene: &Scene,
    accel: &Accel,
    mut ray: crate::scene::Ray,
    first: Option<crate::accel::Hit>,
    u_specular: &mut impl FnMut() -> f32,
    max_specular: u32,
    stats: &mut RayStats,
    sink: impl FnOnce(Option<&Receiver>, Vec3) -> T,
) -> T {
    let mut beta = Vec3::ONE;
    let mut emitted = Vec3::ZERO;
    let mut next = first;
    for bounce in 0..=max_specular {
        if bounce > 0 {
            stats.closest += 1;
            next = accel.intersect(ray.origin, ray.dir, f32::INFINITY);
        }
        let Some(hit) = next else {
            // The sky (and a soft sun) seen directly or through specular bounces.
            if !scene.lights.escaped.is_empty() {
                emitted += beta * scene.escaped(ray.dir);
            }
            break;
        };
        let sp = scene.surface_point(hit.tri, hit.b1, hit.b2);
        let wo = -ray.dir;
        emitted += beta * scene.emitted(hit.tri, sp.ng, sp.uv, wo);
        let bsdf = Bsdf::new(scene.material_of(hit.tri).bsdf_kind(sp.uv, &scene.textures), sp.ns, sp.ng, wo);
        if !bsdf.is_delta() {
            return sink(Some(&Receiver { sp, bsdf, wo, beta }), emitted);
        }
        if bounce == max_specular {
            break;
        }
        let Some(bs) = bsdf.sample(wo, u_specular(), glam::Vec2::splat(0.5), crate::bsdf::TransportMode::Radiance)
        else {
            break;
        };
        beta *= bs.f * (bsdf.abs_cos(bs.wi) / bs.pdf_w);
        ray = crate::scene::Ray { origin: offset_origin(&sp, &scene.mesh.corners(hit.tri), bs.wi), dir: bs.wi };
    }
    sink(None, emitted)
}
