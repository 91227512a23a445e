//! Watertight ray/triangle intersection (Woop, Benthin & Wald 2013, JCGT 2(1)).
//!
//! The ray is sheared so that it points along +z; every triangle edge function is then computed
//! from the same sheared vertex coordinates, so a ray through an edge or vertex shared by two
//! triangles is reported by at least one of them (obvhs's Möller–Trumbore test is not watertight
//! and leaks light through the diagonals of quads). Edge functions that round to exactly zero are
//! recomputed in double precision, as the paper prescribes.

use glam::{Vec3, Vec3A};

/// The per-ray constants of the watertight test.
#[derive(Clone, Copy, Debug)]
pub struct ShearedRay {
    /// Ray origin.
    pub origin: Vec3A,
    /// Index of the dominant axis of the direction.
    pub kz: usize,
    /// The axis after `kz` (swapped with `ky` when `dir[kz] < 0` to keep the winding).
    pub kx: usize,
    /// The remaining axis.
    pub ky: usize,
    /// Shear constants: x' = x − sx·z, y' = y − sy·z, z' = sz·z.
    pub sx: f32,
    /// See `sx`.
    pub sy: f32,
    /// See `sx`.
    pub sz: f32,
}

impl ShearedRay {
    /// Precomputes the shear for a ray (direction need not be normalised but must be non-zero).
    #[inline]
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        let a = dir.abs();
        let kz = if a.x > a.y {
            if a.x > a.z { 0 } else { 2 }
        } else if a.y > a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let dz = dir[kz];
        ShearedRay { origin: origin.into(), kz, kx, ky, sx: dir[kx] / dz, sy: dir[ky] / dz, sz: 1.0 / dz }
    }
}

/// A triangle hit: distance and barycentrics (b1 weights p1, b2 weights p2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriHit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// Barycentric weight of the second vertex.
    pub b1: f32,
    /// Barycentric weight of the third vertex.
    pub b2: f32,
}

/// Intersects a sheared ray with triangle (p0, p1, p2) within (t_min, t_max]; both faces hit.
#[inline(always)]
pub fn intersect(ray: &ShearedRay, p0: Vec3A, p1: Vec3A, p2: Vec3A, t_min: f32, t_max: f32) -> Option<TriHit> {
    let a = p0 - ray.origin;
    let b = p1 - ray.origin;
    let c = p2 - ray.origin;
    let (kx, ky, kz) = (ray.kx, ray.ky, ray.kz);
    let ax = a[kx] - ray.sx * a[kz];
    let ay = a[ky] - ray.sy * a[kz];
    let bx = b[kx] - ray.sx * b[kz];
    let by = b[ky] - ray.sy * b[kz];
    let cx = c[kx] - ray.sx * c[kz];
    let cy = c[ky] - ray.sy * c[kz];
    let mut u = cx * by - cy * bx;
    let mut v = ax * cy - ay * cx;
    let mut w = bx * ay - by * ax;
    if u == 0.0 || v == 0.0 || w == 0.0 {
        u = (cx as f64 * by as f64 - cy as f64 * bx as f64) as f32;
        v = (ax as f64 * cy as f64 - ay as f64 * cx as f64) as f32;
        w = (bx as f64 * ay as f64 - by as f64 * ax as f64) as f32;
    }
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }
    let az = ray.sz * a[kz];
    let bz = ray.sz * b[kz];
    let cz = ray.sz * c[kz];
    let t_scaled = u * az + v * bz + w * cz;
    let inv_det = 1.0 / det;
    let t = t_scaled * inv_det;
    if !(t > t_min && t <= t_max) {
        return None;
    }
    Some(TriHit { t, b1: v * inv_det, b2: w * inv_det })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;

    #[test]
    fn hits_inside_and_misses_outside_with_correct_barycentrics() {
        let (p0, p1, p2) = (Vec3A::new(0.0, 0.0, 0.0), Vec3A::new(1.0, 0.0, 0.0), Vec3A::new(0.0, 1.0, 0.0));
        let r = ShearedRay::new(Vec3::new(0.25, 0.5, 1.0), Vec3::new(0.0, 0.0, -1.0));
        let h = intersect(&r, p0, p1, p2, 0.0, f32::INFINITY).unwrap();
        assert!((h.t - 1.0).abs() < 1e-6 && (h.b1 - 0.25).abs() < 1e-6 && (h.b2 - 0.5).abs() < 1e-6);
        let r = ShearedRay::new(Vec3::new(0.75, 0.5, 1.0), Vec3::new(0.0, 0.0, -1.0));
        assert!(intersect(&r, p0, p1, p2, 0.0, f32::INFINITY).is_none());
        // Back side and t range.
        let r = ShearedRay::new(Vec3::new(0.25, 0.25, -1.0), Vec3::new(0.0, 0.0, 1.0));
        assert!(intersect(&r, p0, p1, p2, 0.0, 2.0).is_some());
        assert!(intersect(&r, p0, p1, p2, 0.0, 0.5).is_none());
    }

    /// Rays aimed exactly at points of the shared diagonal of a quad (and at its corners)
    /// always hit one of the two triangles.
    #[test]
    fn shared_edges_and_vertices_never_leak() {
        let mut rng = Pcg32::new(12);
        for _ in 0..20_000 {
            let corner =
                Vec3::new(rng.next_f32() * 10.0 - 5.0, rng.next_f32() * 10.0 - 5.0, rng.next_f32() * 10.0 - 5.0);
            let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 3.0 - 1.5;
            let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 3.0 - 1.5;
            let (a, b, c, d) = (corner, corner + u, corner + u + v, corner + v);
            let s = rng.next_f32();
            let target = match rng.next_below(3) {
                0 => a + (c - a) * s,
                1 => a,
                _ => c,
            };
            let origin = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 40.0 - 20.0;
            let r = ShearedRay::new(origin, target - origin);
            let h1 = intersect(&r, a.into(), b.into(), c.into(), 0.0, f32::INFINITY);
            let h2 = intersect(&r, a.into(), c.into(), d.into(), 0.0, f32::INFINITY);
            if u.cross(v).length() < 1e-3 {
                continue;
            }
            assert!(h1.is_some() || h2.is_some(), "leak at {target} from {origin}");
        }
    }
}
