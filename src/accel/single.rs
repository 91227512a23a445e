//! Single-ray queries through obvhs's CWBVH traversal, with our watertight triangle test.

use glam::Vec3;
use obvhs::ray::{Ray as BvhRay, RayHit};

use super::triangle::{ShearedRay, intersect};
use super::{Accel, Hit};
use crate::scene::{Scene, SurfacePoint};

/// A world-space ray mapped to the canonical frame: origin, unit direction, t_max, and the
/// factor converting canonical distances back to the caller's ray parameter.
#[inline]
fn canonical(accel: &Accel, origin: Vec3, dir: Vec3, t_max: f32) -> Option<(Vec3, Vec3, f32, f32)> {
    let len = dir.length();
    if !(len > 0.0) || !(t_max > 0.0) || !len.is_finite() {
        return None;
    }
    let to_param = 1.0 / (len * accel.frame.scale);
    let t_max_c = if t_max.is_finite() { t_max / to_param } else { f32::INFINITY };
    Some((accel.frame.point(origin), dir / len, t_max_c, to_param))
}

impl Accel {
    /// The closest hit along `origin + t·dir` for t in (0, t_max] (world space; `dir` need not
    /// be normalised, `t` is in units of its length).
    #[inline]
    pub fn intersect(&self, origin: Vec3, dir: Vec3, t_max: f32) -> Option<Hit> {
        let (origin, dir, t_max, to_param) = canonical(self, origin, dir, t_max)?;
        let sheared = ShearedRay::new(origin, dir);
        let ray = BvhRay::new(origin.into(), dir.into(), 0.0, t_max);
        let mut hit = RayHit::none();
        let mut best = (0.0f32, 0.0f32);
        let mut best_t = t_max;
        let found = self.bvh.ray_traverse(ray, &mut hit, |r, prim| {
            let [p0, p1, p2] = self.tris[prim];
            match intersect(&sheared, p0, p1, p2, 0.0, r.tmax) {
                Some(h) if h.t < best_t => {
                    best_t = h.t;
                    best = (h.b1, h.b2);
                    h.t
                }
                Some(h) => h.t,
                None => f32::INFINITY,
            }
        });
        if !found {
            return None;
        }
        Some(Hit { t: hit.t * to_param, tri: self.prim_to_tri[hit.primitive_id as usize], b1: best.0, b2: best.1 })
    }

    /// True when something blocks `origin + t·dir` for t in (0, t_max).
    #[inline]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        let Some((origin, dir, t_max, _)) = canonical(self, origin, dir, t_max) else { return false };
        let sheared = ShearedRay::new(origin, dir);
        let ray = BvhRay::new(origin.into(), dir.into(), 0.0, t_max);
        !self.bvh.ray_traverse_miss(ray, |_, prim| {
            let [p0, p1, p2] = self.tris[prim];
            match intersect(&sheared, p0, p1, p2, 0.0, t_max) {
                Some(h) if h.t < t_max => h.t,
                _ => f32::INFINITY,
            }
        })
    }

    /// Visibility between two surface points (offsetting both ends, see the module doc).
    pub fn visible(&self, scene: &Scene, a: &SurfacePoint, b: &SurfacePoint) -> bool {
        let ca = scene.mesh.corners(a.tri);
        let cb = scene.mesh.corners(b.tri);
        let oa = super::offset_origin(a, &ca, b.p - a.p);
        let ob = super::offset_origin(b, &cb, a.p - b.p);
        !self.occluded(oa, ob - oa, 1.0 - 1e-4)
    }
}
