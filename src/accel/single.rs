//! Single-ray queries through obvhs's CWBVH traversal, with our watertight triangle test.

use glam::Vec3;
use obvhs::ray::{Ray as BvhRay, RayHit};

use super::triangle::{ShearedRay, intersect};
use super::{Accel, Hit};
use crate::scene::{Scene, SurfacePoint};

impl Accel {
    /// The closest hit along `origin + t·dir` for t in (0, t_max].
    #[inline]
    pub fn intersect(&self, origin: Vec3, dir: Vec3, t_max: f32) -> Option<Hit> {
        if !(t_max > 0.0) || dir == Vec3::ZERO {
            return None;
        }
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
        Some(Hit { t: hit.t, tri: self.prim_to_tri[hit.primitive_id as usize], b1: best.0, b2: best.1 })
    }

    /// True when something blocks `origin + t·dir` for t in (0, t_max).
    #[inline]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        if !(t_max > 0.0) || dir == Vec3::ZERO {
            return false;
        }
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
