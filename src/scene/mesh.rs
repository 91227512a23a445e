//! All triangles of a scene in one indexed mesh, in world space.

use glam::{Vec2, Vec3};

/// Marker for "no emitter" in [`Mesh::emitter`].
pub const NO_LIGHT: u32 = u32::MAX;

/// The merged triangle mesh.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Vertex normals, one per position, `Vec3::ZERO` where the source had none (flat
    /// shading); empty when no mesh of the scene has any.
    pub normals: Vec<Vec3>,
    /// Vertex texture coordinates, one per position (zero where absent); empty when no mesh of
    /// the scene has any.
    pub uvs: Vec<Vec2>,
    /// Vertex indices of each triangle (counter-clockwise = front).
    pub triangles: Vec<[u32; 3]>,
    /// Material of each triangle.
    pub material: Vec<u32>,
    /// Light index of each emitting triangle, [`NO_LIGHT`] otherwise.
    pub emitter: Vec<u32>,
}

/// A point on a surface with its local geometry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    /// Position.
    pub p: Vec3,
    /// Unit geometric normal from the winding (front side), not flipped towards any viewer.
    pub ng: Vec3,
    /// Unit shading normal, on the same side as `ng`.
    pub ns: Vec3,
    /// Texture coordinates.
    pub uv: Vec2,
    /// Triangle index.
    pub tri: u32,
}

impl Mesh {
    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// Bytes the mesh's arrays hold.
    pub fn heap_bytes(&self) -> usize {
        use std::mem::size_of_val;
        size_of_val(&self.positions[..])
            + size_of_val(&self.normals[..])
            + size_of_val(&self.uvs[..])
            + size_of_val(&self.triangles[..])
            + size_of_val(&self.material[..])
            + size_of_val(&self.emitter[..])
    }

    /// True when the mesh has no triangles.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// The three corner positions of triangle `tri`.
    #[inline]
    pub fn corners(&self, tri: u32) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[tri as usize];
        [self.positions[a as usize], self.positions[b as usize], self.positions[c as usize]]
    }

    /// Area of triangle `tri`.
    pub fn area(&self, tri: u32) -> f32 {
        let [p0, p1, p2] = self.corners(tri);
        0.5 * (p1 - p0).cross(p2 - p0).length()
    }

    /// The surface point at barycentrics (b1, b2) of triangle `tri`
    /// (`p = (1 − b1 − b2) p0 + b1 p1 + b2 p2`).
    #[inline(always)]
    pub fn surface_point(&self, tri: u32, b1: f32, b2: f32) -> SurfacePoint {
        let [i0, i1, i2] = self.triangles[tri as usize];
        let (i0, i1, i2) = (i0 as usize, i1 as usize, i2 as usize);
        let b0 = 1.0 - b1 - b2;
        let (p0, p1, p2) = (self.positions[i0], self.positions[i1], self.positions[i2]);
        let p = p0 * b0 + p1 * b1 + p2 * b2;
        let ng = (p1 - p0).cross(p2 - p0).normalize();
        let ns = if self.normals.is_empty() {
            ng
        } else {
            let n = self.normals[i0] * b0 + self.normals[i1] * b1 + self.normals[i2] * b2;
            match n.try_normalize() {
                Some(ns) if ns.dot(ng) >= 0.0 => ns,
                Some(ns) => -ns,
                None => ng,
            }
        };
        let uv =
            if self.uvs.is_empty() { Vec2::ZERO } else { self.uvs[i0] * b0 + self.uvs[i1] * b1 + self.uvs[i2] * b2 };
        SurfacePoint { p, ng, ns, uv, tri }
    }
}
