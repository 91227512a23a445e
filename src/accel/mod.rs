//! ③ The acceleration structure: the only importer of obvhs.
//!
//! [`Accel::build`] builds obvhs's compressed 8-wide BVH (CWBVH, Ylitie et al. 2017) over the
//! scene's triangles and keeps a copy of the triangles in BVH leaf order, intersected with our
//! watertight test ([`triangle`]). Queries: closest hit and occlusion for single rays
//! ([`single`]). Debug builds validate the tree after building.
//!
//! **Canonical frame.** obvhs's CWBVH node test clips every ray at an absolute t of 1e-4
//! (`cwbvh::node::EPSILON`), which at small scene scales skips nearby geometry (light leaks in
//! corners; a Cornell box scaled by 1e-3 rendered visibly darker contact shadows). The BVH is
//! therefore built over the triangles mapped into a canonical frame, `x' = (x − centre)·k` with
//! k making the scene's bounding-box diagonal 2²⁰, and rays are mapped with unit directions.
//! The clip distance is then ~1e-10 of the scene size, far below the ray offsets below, and
//! the structure behaves identically at every scene scale.
//!
//! **Offset policy for rays leaving a surface** (the same for single rays and packets): the
//! origin is moved off the surface along the geometric normal, towards the side the ray leaves
//! on, by [`ray_offset`] = 2⁻¹⁸ × the largest absolute coordinate of the triangle and the point
//! (a few hundred ulps of the position, so the offset scales with the scene and is far above the
//! rounding error of the hit point), and rays start at t = 0. Shadow rays between two surface
//! points offset both ends and stop at the offset end point, so the receiving surface itself is
//! never reported as an occluder.

pub mod single;
pub mod triangle;

use glam::{Vec3, Vec3A};
use obvhs::BvhBuildParams;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::builder::build_cwbvh_from_tris;
use obvhs::triangle::Triangle;

use crate::scene::{Mesh, SurfacePoint};

pub use triangle::{ShearedRay, TriHit, intersect as intersect_triangle};

/// A closest-hit result.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the ray (in units of the direction's length).
    pub t: f32,
    /// Scene triangle index.
    pub tri: u32,
    /// Barycentric weight of the triangle's second vertex.
    pub b1: f32,
    /// Barycentric weight of the triangle's third vertex.
    pub b2: f32,
}

/// The map from world space to the canonical frame of the BVH (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CanonicalFrame {
    /// World-space centre of the scene bounds.
    pub center: Vec3,
    /// World → canonical scale factor.
    pub scale: f32,
}

/// Diagonal of the scene bounds in the canonical frame.
pub const CANONICAL_DIAGONAL: f32 = 1_048_576.0;

impl CanonicalFrame {
    /// A world point in the canonical frame.
    #[inline]
    pub fn point(&self, p: Vec3) -> Vec3 {
        (p - self.center) * self.scale
    }
}

/// The BVH with its triangles in leaf order.
pub struct Accel {
    /// World → canonical frame map.
    pub frame: CanonicalFrame,
    pub(crate) bvh: CwBvh,
    /// Triangle corners in BVH primitive order.
    pub(crate) tris: Vec<[Vec3A; 3]>,
    /// Scene triangle index of each BVH primitive.
    pub(crate) prim_to_tri: Vec<u32>,
}

impl std::fmt::Debug for Accel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Accel").field("triangles", &self.tris.len()).field("nodes", &self.bvh.nodes.len()).finish()
    }
}

impl Accel {
    /// Builds the BVH over all triangles of `mesh` (must be non-empty).
    pub fn build(mesh: &Mesh) -> Accel {
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for p in &mesh.positions {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        let diag = (hi - lo).length();
        let scale = if diag > 0.0 && diag.is_finite() { CANONICAL_DIAGONAL / diag } else { 1.0 };
        let frame = CanonicalFrame { center: 0.5 * (lo + hi), scale };
        let tris: Vec<Triangle> = (0..mesh.len() as u32)
            .map(|t| {
                let [a, b, c] = mesh.corners(t).map(|p| frame.point(p));
                Triangle { v0: a.into(), v1: b.into(), v2: c.into() }
            })
            .collect();
        let mut build_time = std::time::Duration::ZERO;
        let bvh = build_cwbvh_from_tris(&tris, BvhBuildParams::medium_build(), &mut build_time);
        let prim_to_tri: Vec<u32> = bvh.primitive_indices.clone();
        let ordered = prim_to_tri.iter().map(|&i| {
            let t = &tris[i as usize];
            [t.v0, t.v1, t.v2]
        });
        let accel = Accel { frame, tris: ordered.collect(), prim_to_tri, bvh };
        debug_assert!(accel.validate(mesh));
        accel
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    /// Checks that every scene triangle appears exactly once and its copy matches the mesh.
    pub fn validate(&self, mesh: &Mesh) -> bool {
        let mut seen = vec![false; mesh.len()];
        for (prim, &tri) in self.prim_to_tri.iter().enumerate() {
            let t = tri as usize;
            if t >= seen.len() || seen[t] {
                return false;
            }
            seen[t] = true;
            let c = mesh.corners(tri).map(|p| self.frame.point(p));
            if (0..3).any(|k| Vec3::from(self.tris[prim][k]) != c[k]) {
                return false;
            }
        }
        seen.iter().all(|&s| s)
    }
}

/// How far a ray leaving a surface point is moved off it (see the module doc).
#[inline]
pub fn ray_offset(p: Vec3, corners: &[Vec3; 3]) -> f32 {
    let m = corners.iter().fold(p.abs().max_element(), |m, c| m.max(c.abs().max_element()));
    m * (1.0 / 262_144.0) + f32::MIN_POSITIVE
}

/// The origin for a ray leaving surface point `sp` (on a triangle with `corners`) in direction
/// `w`: offset along the geometric normal towards `w`'s side.
#[inline]
pub fn offset_origin(sp: &SurfacePoint, corners: &[Vec3; 3], w: Vec3) -> Vec3 {
    let d = ray_offset(sp.p, corners);
    if sp.ng.dot(w) >= 0.0 { sp.p + sp.ng * d } else { sp.p - sp.ng * d }
}
