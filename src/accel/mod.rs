//! ③ The acceleration structure: the only importer of obvhs.
//!
//! [`Accel::build`] has obvhs build a BVH2 over the scene's triangles (PLOC with parallel
//! reinsertion, the same builder as its `build_cwbvh_from_tris`) and converts it twice:
//!
//! - into **our flattened 8-wide BVH** ([`wide`]): full-precision child boxes in SoA form and
//!   leaves of up to four triangles in SoA blocks. All queries use it: single rays
//!   ([`single`]: 8 children per SIMD box test, 4 triangles per SIMD triangle test) and packets
//!   of 4 or 8 rays ([`packet`]: one child or triangle against all lanes). Packet builders for
//!   the gather's patterns are in [`rays`].
//! - into **obvhs's compressed CWBVH** (Ylitie et al. 2017), only when asked
//!   ([`Accel::build_with_obvhs`]): the baseline the benchmarks and the agreement tests compare
//!   with ([`Accel::intersect_obvhs`], [`Accel::occluded_obvhs`]). Renders keep only our tree.
//!
//! Triangles are intersected with our watertight test ([`triangle`]) in every path, in the
//! same arithmetic, so single rays, packet lanes and the obvhs path report the same triangle
//! and t (ties at equal t go to the smaller scene index). Debug builds validate both trees.
//!
//! **Canonical frame.** obvhs's CWBVH node test clips every ray at an absolute t of 1e-4
//! (`cwbvh::node::EPSILON`), which at small scene scales skips nearby geometry (light leaks in
//! corners; a Cornell box scaled by 1e-3 rendered visibly darker contact shadows). The BVH is
//! therefore built over the triangles mapped into a canonical frame, `x' = (x − centre)·k` with
//! k making the scene's bounding-box diagonal 2²⁰, and rays are mapped with unit directions.
//! The clip distance is then ~1e-10 of the scene size, far below the ray offsets below, and
//! the structure behaves identically at every scene scale. Our own traversals have no clip
//! (rays start at t = 0) but share the frame.
//!
//! **Offset policy for rays leaving a surface** (the same for single rays and packets): the
//! origin is moved off the surface along the geometric normal, towards the side the ray leaves
//! on, by [`ray_offset`] = 2⁻¹⁸ × the largest absolute coordinate of the triangle and the point
//! (a few hundred ulps of the position, so the offset scales with the scene and is far above the
//! rounding error of the hit point), and rays start at t = 0. Shadow rays between two surface
//! points offset both ends and stop at the offset end point ([`shadow_segment`],
//! [`SHADOW_T_MAX`]), so the receiving surface itself is never reported as an occluder.
//!
//! **Robustness.** Directions with zero components get infinite reciprocals and the slab
//! tests treat boxes as closed (see [`single`]); box far distances are scaled up by
//! [`single::ROBUST`] and culling has an absolute margin so that rounding never culls a box
//! holding a hit; rays with zero or non-finite direction, or
//! t_max ≤ 0 or NaN, hit nothing (inactive packet lanes); nothing panics on NaN input.

pub mod batch;
pub mod packet;
pub mod rays;
pub mod single;
pub mod triangle;
pub mod wide;

use glam::{Vec3, Vec3A};
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh;
use obvhs::ploc::PlocBuilder;
use obvhs::triangle::Triangle;

use crate::scene::{Mesh, SurfacePoint};

pub use packet::{PacketHits, PacketView};
pub use triangle::{ShearedRay, TriHit, intersect as intersect_triangle};
pub use wide::WideBvh;

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

/// The BVHs with their triangles in leaf order.
pub struct Accel {
    /// World → canonical frame map.
    pub frame: CanonicalFrame,
    /// Our 8-wide BVH (all queries).
    pub(crate) wide: WideBvh<8>,
    /// obvhs's CWBVH with its triangles, built only when asked ([`Accel::build_with_obvhs`]):
    /// the benchmarks' and the agreement tests' baseline; renders do not keep it.
    pub(crate) obvhs: Option<ObvhsBaseline>,
}

/// obvhs's compressed CWBVH over the same BVH2 as ours, with its triangles in its primitive order.
pub(crate) struct ObvhsBaseline {
    pub(crate) bvh: CwBvh,
    /// Triangle corners in CWBVH primitive order.
    pub(crate) tris: Vec<[Vec3A; 3]>,
    /// Scene triangle index of each CWBVH primitive.
    pub(crate) prim_to_tri: Vec<u32>,
}

impl std::fmt::Debug for Accel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Accel")
            .field("triangles", &self.triangle_count())
            .field("wide_nodes", &self.wide.nodes.len())
            .field("wide_depth", &self.wide.depth)
            .field("cwbvh_nodes", &self.obvhs.as_ref().map(|o| o.bvh.nodes.len()))
            .finish()
    }
}

impl Accel {
    /// Builds the BVH over all triangles of `mesh` (must be non-empty).
    pub fn build(mesh: &Mesh) -> Accel {
        Self::build_inner(mesh, false)
    }

    /// [`Accel::build`], also keeping obvhs's CWBVH of the same BVH2 for
    /// [`Accel::intersect_obvhs`] / [`Accel::occluded_obvhs`] (benchmarks and agreement tests).
    pub fn build_with_obvhs(mesh: &Mesh) -> Accel {
        Self::build_inner(mesh, true)
    }

    fn build_inner(mesh: &Mesh, keep_obvhs: bool) -> Accel {
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for p in &mesh.positions {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        let diag = (hi - lo).length();
        let scale = if diag > 0.0 && diag.is_finite() { CANONICAL_DIAGONAL / diag } else { 1.0 };
        let frame = CanonicalFrame { center: 0.5 * (lo + hi), scale };
        let corner = |t: u32| mesh.corners(t).map(|p| frame.point(p));
        let triangle = |t: u32| {
            let [a, b, c] = corner(t);
            Triangle { v0: a.into(), v1: b.into(), v2: c.into() }
        };
        // obvhs's `build_cwbvh_from_tris` (medium preset, no pre-splits), keeping the BVH2. PLOC
        // reads only the triangles' boxes: they are built here and freed at once, so that the
        // build's peak memory is not the scene's.
        let params = BvhBuildParams::medium_build();
        let boxes: Vec<Aabb> = (0..mesh.len() as u32).map(|t| triangle(t).aabb()).collect();
        let mut bvh2 = PlocBuilder::with_capacity(boxes.len()).build(
            params.ploc_search_distance,
            &boxes,
            (0..boxes.len() as u32).collect(),
            params.sort_precision,
            params.search_depth_threshold,
        );
        drop(boxes);
        ReinsertionOptimizer::default().run(&mut bvh2, params.reinsertion_batch_ratio, None);
        let obvhs = keep_obvhs.then(|| {
            let bvh = bvh2_to_cwbvh(&bvh2, params.max_prims_per_leaf.clamp(1, 3), true, false);
            let prim_to_tri: Vec<u32> = bvh.primitive_indices.clone();
            let tris = prim_to_tri
                .iter()
                .map(|&i| {
                    let t = triangle(i);
                    [t.v0, t.v1, t.v2]
                })
                .collect();
            ObvhsBaseline { bvh, tris, prim_to_tri }
        });
        let wide = WideBvh::from_bvh2(&bvh2, corner);
        drop(bvh2);
        let accel = Accel { frame, wide, obvhs };
        debug_assert!(accel.validate(mesh));
        accel
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.wide.blocks.iter().map(|b| b.len()).sum()
    }

    /// Bytes the structure holds (nodes and leaf triangles; the obvhs baseline's too when kept).
    pub fn heap_bytes(&self) -> usize {
        use std::mem::size_of_val;
        let ours = size_of_val(&self.wide.nodes[..]) + size_of_val(&self.wide.blocks[..]);
        ours + self.obvhs.as_ref().map_or(0, |o| {
            size_of_val(&o.bvh.nodes[..])
                + size_of_val(&o.bvh.primitive_indices[..])
                + size_of_val(&o.tris[..])
                + size_of_val(&o.prim_to_tri[..])
        })
    }

    /// Our wide BVH (for statistics and benchmarks).
    pub fn wide(&self) -> &WideBvh<8> {
        &self.wide
    }

    /// Checks the trees: every scene triangle appears exactly once in each and its copies
    /// match the mesh; our tree's boxes contain their contents.
    pub fn validate(&self, mesh: &Mesh) -> bool {
        if !self.wide.validate(mesh.len()) {
            return false;
        }
        for block in &self.wide.blocks {
            for lane in 0..block.len() {
                let c = mesh.corners(block.id[lane]).map(|p| self.frame.point(p));
                if (0..3).any(|k| Vec3::from(block.corner(lane, k)) != c[k]) {
                    return false;
                }
            }
        }
        let Some(o) = &self.obvhs else { return true };
        let mut seen = vec![false; mesh.len()];
        for (prim, &tri) in o.prim_to_tri.iter().enumerate() {
            let t = tri as usize;
            if t >= seen.len() || seen[t] {
                return false;
            }
            seen[t] = true;
            let c = mesh.corners(tri).map(|p| self.frame.point(p));
            if (0..3).any(|k| Vec3::from(o.tris[prim][k]) != c[k]) {
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

/// Fraction of a shadow segment that is tested: the far end's own surface is not an occluder.
pub const SHADOW_T_MAX: f32 = 1.0 - 1e-4;

/// The shadow segment between surface points `a` and `b`, both ends offset off their surfaces
/// towards each other: returns (origin, end); trace `origin + t·(end − origin)` for t in
/// (0, [`SHADOW_T_MAX`]).
#[inline]
pub fn shadow_segment(scene: &crate::scene::Scene, a: &SurfacePoint, b: &SurfacePoint) -> (Vec3, Vec3) {
    let oa = offset_origin(a, &scene.mesh.corners(a.tri), b.p - a.p);
    let ob = offset_origin(b, &scene.mesh.corners(b.tri), a.p - b.p);
    (oa, ob)
}
