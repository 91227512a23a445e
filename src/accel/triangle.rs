//! Watertight ray/triangle intersection (Woop, Benthin & Wald 2013, JCGT 2(1)).
//!
//! The ray is sheared so that it points along +z; every triangle edge function is then computed
//! from the same sheared vertex coordinates, so a ray through an edge or vertex shared by two
//! triangles is reported by at least one of them (obvhs's Möller–Trumbore test is not watertight
//! and leaks light through the diagonals of quads). Edge functions that round to exactly zero are
//! recomputed in double precision, as the paper prescribes.
//!
//! Three forms of the same arithmetic, giving bit-identical results for a (ray, triangle) pair:
//! [`intersect`] (scalar, the reference twin), [`intersect_block`] (one ray against the four
//! triangles of a [`TriBlock`], SIMD across triangles: single-ray leaves) and
//! [`intersect_packet`] (one triangle against a [`ShearPacket`], SIMD across rays). The shared
//! lane kernel is [`woop_lanes`]; no fused multiply-adds, so every lane rounds exactly as the
//! scalar code does. Agreement is tested lane by lane below.

use glam::{Vec3, Vec3A};

use crate::simd::{F4, Lanes, Vec3x};

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
        // The dominant axis (ties as in: x if it beats y and z, else y if it beats z, else z),
        // chosen without branches: a ray's axis is random to the branch predictor.
        let a = dir.abs();
        let x_max = (a.x > a.y) & (a.x > a.z);
        let kz = (!x_max) as usize * (1 + !(a.y > a.z) as usize);
        let d = dir.to_array();
        // The next two axes, swapped when dir[kz] < 0 to keep the winding.
        let flip = (d[kz] < 0.0) as usize;
        let kx = [[1, 2], [2, 0], [0, 1]][kz][flip];
        let ky = 3 - kz - kx;
        let dz = d[kz];
        ShearedRay { origin: origin.into(), kz, kx, ky, sx: d[kx] / dz, sy: d[ky] / dz, sz: 1.0 / dz }
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

/// Four triangles in structure-of-arrays form: a leaf of the wide BVH (canonical frame).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(16))]
pub struct TriBlock {
    /// `v[3·k + axis][lane]`: coordinate `axis` of corner k of the triangle in `lane`.
    pub v: [[f32; 4]; 9],
    /// Scene triangle index of each lane ([`TriBlock::EMPTY`] for an unused lane).
    pub id: [u32; 4],
}

impl TriBlock {
    /// Id of an unused lane.
    pub const EMPTY: u32 = u32::MAX;

    /// A block of up to four triangles (corners and scene indices); unused lanes are
    /// degenerate (all corners at the first triangle's first corner) and flagged [`Self::EMPTY`].
    pub fn new(tris: &[([Vec3; 3], u32)]) -> TriBlock {
        assert!(!tris.is_empty() && tris.len() <= 4);
        let fill = tris[0].0[0];
        let mut b = TriBlock { v: [[0.0; 4]; 9], id: [Self::EMPTY; 4] };
        for lane in 0..4 {
            let (corners, id) = tris.get(lane).copied().unwrap_or(([fill; 3], Self::EMPTY));
            for (k, c) in corners.iter().enumerate() {
                for axis in 0..3 {
                    b.v[3 * k + axis][lane] = c[axis];
                }
            }
            b.id[lane] = id;
        }
        b
    }

    /// Number of used lanes.
    #[inline]
    pub fn len(&self) -> usize {
        self.id.iter().filter(|&&i| i != Self::EMPTY).count()
    }

    /// True when no lane is used.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Corner k of the triangle in `lane`.
    #[inline(always)]
    pub fn corner(&self, lane: usize, k: usize) -> Vec3A {
        Vec3A::new(self.v[3 * k][lane], self.v[3 * k + 1][lane], self.v[3 * k + 2][lane])
    }
}

/// Hits of a lane kernel: the mask of lanes with a hit in (0, t_max] and their t and
/// barycentrics (meaningless in other lanes).
#[derive(Clone, Copy, Debug)]
pub struct LaneHits<F: Lanes> {
    /// Lanes with a hit.
    pub mask: F,
    /// Ray parameters.
    pub t: F,
    /// Barycentric weights of the second corners.
    pub b1: F,
    /// Barycentric weights of the third corners.
    pub b2: F,
}

/// The watertight test on lanes: `a*`, `b*`, `c*` are the corners minus the ray origin, in
/// the rays' permuted axes (kx, ky, kz); `s*` the shear constants. Only `lanes` are reported.
/// Lane for lane the same operations, in the same order, as [`intersect`].
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn woop_lanes<F: Lanes>(a: [F; 3], b: [F; 3], c: [F; 3], sx: F, sy: F, sz: F, t_max: F, lanes: F) -> LaneHits<F> {
    let ax = a[0] - sx * a[2];
    let ay = a[1] - sy * a[2];
    let bx = b[0] - sx * b[2];
    let by = b[1] - sy * b[2];
    let cx = c[0] - sx * c[2];
    let cy = c[1] - sy * c[2];
    let mut u = cx * by - cy * bx;
    let mut v = ax * cy - ay * cx;
    let mut w = bx * ay - by * ax;
    let zero = F::splat(0.0);
    let degenerate = u.eq(zero).or(v.eq(zero)).or(w.eq(zero)).and(lanes).bitmask();
    if degenerate != 0 {
        // Edge functions that round to zero: recompute those lanes in double precision.
        let (mut ua, mut va, mut wa) = (u.to_array(), v.to_array(), w.to_array());
        let (ax, ay, bx, by, cx, cy) =
            (ax.to_array(), ay.to_array(), bx.to_array(), by.to_array(), cx.to_array(), cy.to_array());
        let (ax, ay, bx, by, cx, cy) = (ax.as_ref(), ay.as_ref(), bx.as_ref(), by.as_ref(), cx.as_ref(), cy.as_ref());
        for i in 0..F::LANES {
            if degenerate >> i & 1 != 0 {
                ua.as_mut()[i] = (cx[i] as f64 * by[i] as f64 - cy[i] as f64 * bx[i] as f64) as f32;
                va.as_mut()[i] = (ax[i] as f64 * cy[i] as f64 - ay[i] as f64 * cx[i] as f64) as f32;
                wa.as_mut()[i] = (bx[i] as f64 * ay[i] as f64 - by[i] as f64 * ax[i] as f64) as f32;
            }
        }
        (u, v, w) = (F::from_array(ua), F::from_array(va), F::from_array(wa));
    }
    let negative = u.lt(zero).or(v.lt(zero)).or(w.lt(zero));
    let positive = u.gt(zero).or(v.gt(zero)).or(w.gt(zero));
    let det = u + v + w;
    let inside = lanes.and_not(negative.and(positive)).and_not(det.eq(zero));
    let az = sz * a[2];
    let bz = sz * b[2];
    let cz = sz * c[2];
    let t_scaled = u * az + v * bz + w * cz;
    let inv_det = F::splat(1.0) / det;
    let t = t_scaled * inv_det;
    let mask = inside.and(t.gt(zero)).and(t.le(t_max));
    LaneHits { mask, t, b1: v * inv_det, b2: w * inv_det }
}

/// One ray against the first `count` triangles of `block` (lanes = triangles), hits in
/// (0, t_max].
#[inline(always)]
pub fn intersect_block(ray: &ShearedRay, block: &TriBlock, count: usize, t_max: f32) -> LaneHits<F4> {
    let (kx, ky, kz) = (ray.kx, ray.ky, ray.kz);
    let o = ray.origin.to_array();
    let (ox, oy, oz) = (F4::splat(o[kx]), F4::splat(o[ky]), F4::splat(o[kz]));
    let corner = |k: usize| -> [F4; 3] {
        [
            F4::from_array(block.v[3 * k + kx]) - ox,
            F4::from_array(block.v[3 * k + ky]) - oy,
            F4::from_array(block.v[3 * k + kz]) - oz,
        ]
    };
    let valid = F4::first_lanes(count);
    woop_lanes(
        corner(0),
        corner(1),
        corner(2),
        F4::splat(ray.sx),
        F4::splat(ray.sy),
        F4::splat(ray.sz),
        F4::splat(t_max),
        valid,
    )
}

/// The per-ray constants of the watertight test for a packet: each lane exactly the
/// [`ShearedRay`] of its ray, with the origin already permuted into the lane's (kx, ky, kz).
#[derive(Clone, Copy, Debug)]
pub struct ShearPacket<F: Lanes> {
    /// Origin components along (kx, ky, kz) of each lane.
    pub o: [F; 3],
    /// Shear constants.
    pub sx: F,
    /// See `sx`.
    pub sy: F,
    /// See `sx`.
    pub sz: F,
    /// The axes (kx, ky, kz) when every active lane has the same, else per-lane selectors.
    pub axes: Axes<F>,
}

/// How a packet's lanes permute the axes.
#[derive(Clone, Copy, Debug)]
pub enum Axes<F: Lanes> {
    /// All active lanes use (kx, ky, kz).
    Uniform([usize; 3]),
    /// Per lane: for each of kx, ky, kz the masks "axis is 0" and "axis is 1".
    Mixed([[F; 2]; 3]),
}

/// A [`ShearPacket`]'s per-lane constants as scalars ([`ShearPacket::lanes`]).
pub struct ShearLanes<F: Lanes> {
    sx: F::Array,
    sy: F::Array,
    sz: F::Array,
    axes: LaneAxes,
}

/// [`Axes`] with the masks as bits.
enum LaneAxes {
    Uniform([usize; 3]),
    Mixed([[u32; 2]; 3]),
}

impl<F: Lanes> ShearLanes<F> {
    /// Lane `i` as a single sheared ray from `origin` (that lane's origin): exactly the
    /// [`ShearedRay::new`] of the lane, without redoing its divisions. (Read from the packet's
    /// registers lane by lane, every value went through a store and a reload per lane.)
    #[inline(always)]
    pub fn lane(&self, i: usize, origin: Vec3) -> ShearedRay {
        let [kx, ky, kz] = match &self.axes {
            LaneAxes::Uniform(k) => *k,
            LaneAxes::Mixed(bits) => bits.map(|[is0, is1]| {
                if is0 >> i & 1 != 0 {
                    0
                } else if is1 >> i & 1 != 0 {
                    1
                } else {
                    2
                }
            }),
        };
        let (sx, sy, sz) = (self.sx.as_ref()[i], self.sy.as_ref()[i], self.sz.as_ref()[i]);
        ShearedRay { origin: origin.into(), kz, kx, ky, sx, sy, sz }
    }
}

impl<F: Lanes> ShearPacket<F> {
    /// Packs the sheared rays of the lanes in `active` (other lanes get a copy of a valid one).
    pub fn new(rays: &[ShearedRay], active: u32) -> Self {
        debug_assert!(rays.len() >= F::LANES);
        let first = (0..F::LANES).find(|&i| active >> i & 1 != 0).unwrap_or(0);
        let ray = |i: usize| if active >> i & 1 != 0 { rays[i] } else { rays[first] };
        let axes_of = |r: &ShearedRay| [r.kx, r.ky, r.kz];
        let axes0 = axes_of(&ray(first));
        let uniform = (0..F::LANES).all(|i| axes_of(&ray(i)) == axes0);
        let axes = if uniform {
            Axes::Uniform(axes0)
        } else {
            let sel = |j: usize, axis: usize| {
                F::mask_from_bits((0..F::LANES).fold(0, |m, i| m | ((axes_of(&ray(i))[j] == axis) as u32) << i))
            };
            Axes::Mixed([[sel(0, 0), sel(0, 1)], [sel(1, 0), sel(1, 1)], [sel(2, 0), sel(2, 1)]])
        };
        ShearPacket {
            o: [0, 1, 2].map(|j| {
                F::from_fn(|i| {
                    let r = ray(i);
                    r.origin[axes_of(&r)[j]]
                })
            }),
            sx: F::from_fn(|i| ray(i).sx),
            sy: F::from_fn(|i| ray(i).sy),
            sz: F::from_fn(|i| ray(i).sz),
            axes,
        }
    }

    /// The sheared rays of the lanes in `active`, computed on all lanes at once: lane for lane
    /// exactly [`ShearedRay::new`] (same comparisons, same divisions; tested below).
    #[inline]
    pub fn from_lanes(origin: &Vec3x<F>, dir: &Vec3x<F>, active: u32) -> Self {
        let (ax, ay, az) = (dir.x.abs(), dir.y.abs(), dir.z.abs());
        let x_gt_y = ax.gt(ay);
        let m0 = x_gt_y.and(ax.gt(az)); // kz = 0
        let m1 = ay.gt(az).and_not(x_gt_y); // kz = 1
        let m2 = m0.or(m1).mask_not(); // kz = 2
        // Without the swap: kz = 0 → (kx, ky) = (1, 2); kz = 1 → (2, 0); kz = 2 → (0, 1).
        let pick_z = |v: &Vec3x<F>| m0.select(v.x, m1.select(v.y, v.z));
        let pick_x = |v: &Vec3x<F>| m0.select(v.y, m1.select(v.z, v.x));
        let pick_y = |v: &Vec3x<F>| m0.select(v.z, m1.select(v.x, v.y));
        let dz = pick_z(dir);
        let neg = dz.lt(F::splat(0.0));
        let (dx0, dy0) = (pick_x(dir), pick_y(dir));
        let (dx, dy) = (neg.select(dy0, dx0), neg.select(dx0, dy0));
        let (ox0, oy0) = (pick_x(origin), pick_y(origin));
        let o = [neg.select(oy0, ox0), neg.select(ox0, oy0), pick_z(origin)];
        let (b0, b1, bn) = (m0.bitmask() & active, m1.bitmask() & active, neg.bitmask() & active);
        let uniform = [b0, b1, bn].iter().all(|&b| b == 0 || b == active);
        let axes = if uniform {
            let kz = if b0 != 0 {
                0
            } else if b1 != 0 {
                1
            } else {
                2
            };
            let (kx, ky) = ((kz + 1) % 3, (kz + 2) % 3);
            Axes::Uniform(if bn != 0 { [ky, kx, kz] } else { [kx, ky, kz] })
        } else {
            let pos = neg.mask_not();
            Axes::Mixed([
                [m2.and(pos).or(m1.and(neg)), m0.and(pos).or(m2.and(neg))],
                [m1.and(pos).or(m2.and(neg)), m2.and(pos).or(m0.and(neg))],
                [m0, m1],
            ])
        };
        ShearPacket { o, sx: dx / dz, sy: dy / dz, sz: F::splat(1.0) / dz, axes }
    }

    /// The lanes' constants as scalars, unpacked once for tracing the lanes one by one
    /// ([`ShearLanes::lane`]).
    #[inline(always)]
    pub fn lanes(&self) -> ShearLanes<F> {
        let axes = match &self.axes {
            Axes::Uniform(k) => LaneAxes::Uniform(*k),
            Axes::Mixed(sel) => LaneAxes::Mixed(sel.map(|s| s.map(|m| m.bitmask()))),
        };
        ShearLanes { sx: self.sx.to_array(), sy: self.sy.to_array(), sz: self.sz.to_array(), axes }
    }

    /// A corner relative to each lane's origin, in the lane's permuted axes.
    #[inline(always)]
    fn relative(&self, p: Vec3A) -> [F; 3] {
        match &self.axes {
            Axes::Uniform(k) => {
                [F::splat(p[k[0]]) - self.o[0], F::splat(p[k[1]]) - self.o[1], F::splat(p[k[2]]) - self.o[2]]
            }
            Axes::Mixed(sel) => {
                let (x, y, z) = (F::splat(p.x), F::splat(p.y), F::splat(p.z));
                let pick = |j: usize| sel[j][0].select(x, sel[j][1].select(y, z)) - self.o[j];
                [pick(0), pick(1), pick(2)]
            }
        }
    }
}

/// One triangle against the rays of a packet (lanes = rays), hits in (0, t_max] in `lanes`.
#[inline(always)]
pub fn intersect_packet<F: Lanes>(
    ray: &ShearPacket<F>,
    p0: Vec3A,
    p1: Vec3A,
    p2: Vec3A,
    t_max: F,
    lanes: F,
) -> LaneHits<F> {
    woop_lanes(ray.relative(p0), ray.relative(p1), ray.relative(p2), ray.sx, ray.sy, ray.sz, t_max, lanes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;
    use crate::simd::F8;

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

    /// Rays aimed at the centre vertex of a fan of triangles, and at points of its interior
    /// (shared) edges, always hit one of the triangles. (Corners and edges on the *boundary* of
    /// a mesh may rightly be missed by a ray whose rounded direction passes just outside.)
    #[test]
    fn shared_edges_and_vertices_never_leak() {
        let mut rng = Pcg32::new(12);
        for _ in 0..20_000 {
            let c = random_vec(&mut rng, 10.0);
            let (u, v) = (random_vec(&mut rng, 3.0), random_vec(&mut rng, 3.0));
            let n = 3 + rng.next_below(6) as usize;
            let outer: Vec<Vec3> = (0..n)
                .map(|k| {
                    let a = std::f32::consts::TAU * (k as f32 + 0.3 * rng.next_f32()) / n as f32;
                    c + u * a.cos() + v * a.sin()
                })
                .collect();
            if u.cross(v).length() < 1e-3 {
                continue;
            }
            let k = rng.next_below(n as u32) as usize;
            let target = if rng.next_below(3) == 0 { c } else { c + (outer[k] - c) * (0.05 + 0.9 * rng.next_f32()) };
            let origin = random_vec(&mut rng, 40.0);
            let r = ShearedRay::new(origin, target - origin);
            let hit = (0..n).any(|k| {
                intersect(&r, c.into(), outer[k].into(), outer[(k + 1) % n].into(), 0.0, f32::INFINITY).is_some()
            });
            assert!(hit, "leak at {target} from {origin}");
        }
    }

    fn random_vec(rng: &mut Pcg32, s: f32) -> Vec3 {
        Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5) * s
    }

    /// A fan of four triangles around a centre (sharing the centre and, pairwise, edges).
    fn fan(rng: &mut Pcg32) -> [[Vec3; 3]; 4] {
        let c = random_vec(rng, 8.0);
        let (u, v) = (random_vec(rng, 4.0), random_vec(rng, 4.0));
        let outer = [c + u, c + v, c - u, c - v];
        [0, 1, 2, 3].map(|k| [c, outer[k], outer[(k + 1) % 4]])
    }

    /// A ray from a random origin at a corner, an edge, the inside of `tri` or anywhere, some
    /// with axis-parallel directions.
    fn ray_at(rng: &mut Pcg32, tri: &[Vec3; 3]) -> (Vec3, Vec3) {
        let origin = random_vec(rng, 40.0);
        let s = rng.next_f32();
        let target = match rng.next_below(4) {
            0 => tri[0] + (tri[1] - tri[0]) * s,
            1 => tri[rng.next_below(3) as usize],
            2 => tri[0] * 0.3 + tri[1] * 0.3 + tri[2] * 0.4,
            _ => random_vec(rng, 10.0),
        };
        let mut dir = target - origin;
        if rng.next_below(8) == 0 {
            dir[rng.next_below(3) as usize] = 0.0;
        }
        if dir == Vec3::ZERO {
            dir = Vec3::X;
        }
        (origin, dir)
    }

    fn lane_hit<F: Lanes>(h: &LaneHits<F>, lane: usize) -> Option<TriHit> {
        (h.mask.bitmask() >> lane & 1 != 0).then(|| TriHit {
            t: h.t.lane(lane),
            b1: h.b1.lane(lane),
            b2: h.b2.lane(lane),
        })
    }

    #[test]
    fn block_kernel_matches_scalar_lane_by_lane() {
        let mut rng = Pcg32::new(3);
        let mut hits = 0;
        for _ in 0..20_000 {
            let tris = fan(&mut rng);
            let used = 1 + rng.next_below(4) as usize;
            let aim = rng.next_below(used as u32) as usize;
            let (origin, dir) = ray_at(&mut rng, &tris[aim]);
            let r = ShearedRay::new(origin, dir);
            let block =
                TriBlock::new(&tris[..used].iter().enumerate().map(|(i, t)| (*t, i as u32)).collect::<Vec<_>>());
            assert_eq!(block.len(), used);
            for t_max in [f32::INFINITY, 1.0] {
                let h = intersect_block(&r, &block, used, t_max);
                assert_eq!(h.mask.bitmask() >> used, 0);
                for (lane, tri) in tris[..used].iter().enumerate() {
                    let [p0, p1, p2] = tri.map(Vec3A::from);
                    let s = intersect(&r, p0, p1, p2, 0.0, t_max);
                    hits += s.is_some() as u32;
                    assert_eq!(lane_hit(&h, lane), s);
                }
            }
        }
        assert!(hits > 10_000);
    }

    fn packet_matches_scalar<F: Lanes>() {
        let mut rng = Pcg32::new(4);
        let mut hits = 0;
        for _ in 0..10_000 {
            let tri = fan(&mut rng)[0];
            let rays: Vec<ShearedRay> = (0..F::LANES)
                .map(|_| {
                    let (o, d) = ray_at(&mut rng, &tri);
                    ShearedRay::new(o, d)
                })
                .collect();
            let [p0, p1, p2] = tri.map(Vec3A::from);
            for active in [F::ALL, F::ALL & 0b0110_1011] {
                let packet = ShearPacket::<F>::new(&rays, active);
                for t_max in [1e30, 1.0] {
                    let h = intersect_packet(&packet, p0, p1, p2, F::splat(t_max), F::mask_from_bits(active));
                    for (lane, r) in rays.iter().enumerate() {
                        let s = intersect(r, p0, p1, p2, 0.0, t_max).filter(|_| active >> lane & 1 != 0);
                        hits += s.is_some() as u32;
                        assert_eq!(lane_hit(&h, lane), s, "lane {lane}");
                    }
                }
            }
        }
        assert!(hits > 10_000);
    }

    #[test]
    fn packet_kernel_matches_scalar_lane_by_lane() {
        packet_matches_scalar::<F4>();
        packet_matches_scalar::<F8>();
    }

    /// The SIMD construction of a packet's shear equals the scalar one lane by lane, and the
    /// triangle test gives the same answers with either.
    #[test]
    fn shear_packet_from_lanes_matches_scalar_construction() {
        let mut rng = Pcg32::new(9);
        for n in 0..20_000 {
            let tri = fan(&mut rng)[0];
            let rays: Vec<(Vec3, Vec3)> = (0..8)
                .map(|i| {
                    let (o, mut d) = ray_at(&mut rng, &tri);
                    if n % 2 == 0 && i > 0 {
                        d = d * 0.01 + Vec3::new(0.3, -1.0, 0.2); // mostly one dominant axis
                    }
                    (o, d)
                })
                .collect();
            let sheared: Vec<ShearedRay> = rays.iter().map(|&(o, d)| ShearedRay::new(o, d)).collect();
            let active = if n % 3 == 0 { 0b1011_0111 } else { 0xff };
            let a = ShearPacket::<F8>::new(&sheared, active);
            let b =
                ShearPacket::<F8>::from_lanes(&Vec3x::from_fn(|i| rays[i].0), &Vec3x::from_fn(|i| rays[i].1), active);
            let [p0, p1, p2] = tri.map(Vec3A::from);
            let lanes = F8::mask_from_bits(active);
            let (ha, hb) = (
                intersect_packet(&a, p0, p1, p2, F8::splat(1e30), lanes),
                intersect_packet(&b, p0, p1, p2, F8::splat(1e30), lanes),
            );
            for i in (0..8).filter(|i| active >> i & 1 != 0) {
                assert_eq!(a.sx.lane(i).to_bits(), b.sx.lane(i).to_bits());
                assert_eq!(a.sy.lane(i).to_bits(), b.sy.lane(i).to_bits());
                assert_eq!(a.sz.lane(i).to_bits(), b.sz.lane(i).to_bits());
                assert_eq!(lane_hit(&ha, i), lane_hit(&hb, i));
            }
            assert_eq!(matches!(a.axes, Axes::Uniform(_)), matches!(b.axes, Axes::Uniform(_)));
        }
    }

    #[test]
    fn packet_with_one_dominant_axis_uses_the_uniform_path() {
        let rays = [ShearedRay::new(Vec3::ZERO, Vec3::new(0.1, 0.2, 1.0)); 8];
        assert!(matches!(ShearPacket::<F8>::new(&rays, 0xff).axes, Axes::Uniform([0, 1, 2])));
    }
}
