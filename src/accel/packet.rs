//! Packet traversal: 4 or 8 coherent rays through our wide BVH at once (Wald, Slusallek,
//! Benthin & Wagner 2001, "Interactive rendering with coherent ray tracing"; on wide nodes as
//! in Embree's packet kernels).
//!
//! - **Node test:** each child box against all lanes with one SIMD operation per plane, the
//!   same slab test as single rays (near plane by each lane's direction sign, NaN slabs of rays
//!   lying in a face ignored, far distance scaled by [`ROBUST`], culling by
//!   [`super::single::cull_distance`]). A child is visited when *any* active lane hits
//!   it; its stack entry keeps every lane's entry distance (+∞ for lanes that missed), so on
//!   popping, only lanes whose closest hit lies beyond the entry are still active.
//! - **Order:** children are visited front to back along the packet's dominant direction (the
//!   octant of the sum of its directions), from the per-node order lists built with the tree.
//! - **Triangles:** one triangle against all lanes at once ([`intersect_packet`]), with the same
//!   arithmetic as the single-ray test so every lane gets exactly the single ray's answer.
//! - **Occlusion:** a lane leaves the packet as soon as it is blocked (its t_max becomes −∞),
//!   and the traversal stops when every lane is blocked.
//! - **Offsets:** packets carry world rays exactly as single rays do; rays leaving a surface
//!   use [`super::offset_origin`] (see the builders in [`super::rays`]).
//!
//! Each lane is mapped to the canonical frame by the same scalar code as a single ray
//! ([`Accel::canonical`]), so hit/miss, triangle and t equal [`Accel::intersect`]'s.
//! Zero-length, NaN or t_max ≤ 0 lanes are inactive and report no hit.

use glam::{Vec3, Vec3A};

use super::single::{
    CULL_SLACK, CanonicalRay, NO_OCCLUDER, ROBUST, SpillStack, closest, occluded_from_parts, prefetch_ref,
};
use super::triangle::{ShearPacket, TriBlock, intersect_packet};
use super::wide::{EMPTY, LEAF_BIT, Node, WideBvh, leaf_parts, octant};
use super::{Accel, Hit};
use crate::simd::{F8, Lanes, RayPacket, Vec3x};

mod lanewise;

/// Closest hits of a packet, lane by lane.
#[derive(Clone, Copy, Debug)]
pub struct PacketHits<F: Lanes> {
    /// Bit i set when lane i hit something.
    pub hit: u32,
    /// Distances in units of each lane's direction length.
    pub t: F,
    /// Scene triangle indices as bit patterns (read with [`PacketHits::tri`]).
    pub tri_bits: F,
    /// Barycentric weights of the second corners.
    pub b1: F,
    /// Barycentric weights of the third corners.
    pub b2: F,
}

impl<F: Lanes> PacketHits<F> {
    /// The scene triangle hit by lane `i` (meaningless when the lane missed).
    #[inline]
    pub fn tri(&self, i: usize) -> u32 {
        self.tri_bits.lane_bits(i)
    }

    /// The first `out.len()` lanes as single-ray results, with the lanes' values unpacked once
    /// (not through a store and a reload per lane and value, as [`PacketHits::lane`] in a loop).
    #[inline(always)]
    pub fn write_lanes(&self, out: &mut [Option<Hit>]) {
        let [t, tri, b1, b2] = [self.t, self.tri_bits, self.b1, self.b2].map(F::to_array);
        for (i, o) in out.iter_mut().enumerate() {
            *o = (self.hit >> i & 1 != 0).then(|| Hit {
                t: t.as_ref()[i],
                tri: tri.as_ref()[i].to_bits(),
                b1: b1.as_ref()[i],
                b2: b2.as_ref()[i],
            });
        }
    }

    /// Lane `i` as a single-ray result.
    #[inline]
    pub fn lane(&self, i: usize) -> Option<Hit> {
        (self.hit >> i & 1 != 0).then(|| Hit {
            t: self.t.lane(i),
            tri: self.tri(i),
            b1: self.b1.lane(i),
            b2: self.b2.lane(i),
        })
    }
}

/// Conservative culling of the children of a node for a whole packet.
trait Cull {
    /// Lower bounds of the lanes' entry distances into the 8 children, and the mask of the
    /// children that some lane may enter at or before `t_cull`.
    fn test(&self, bounds: &[[f32; 8]; 6], t_cull: f32) -> (F8, u32);
    /// The children among the 8 of `bounds` (entered at `t_near`) that, when they pass
    /// [`Cull::test`], also get the exact per-lane box test (leaves always do).
    fn lane_tests(&self, bounds: &[[f32; 8]; 6], t_near: F8) -> u32;
}

/// Widest spread of a packet's direction slopes (tangents about its central axis) that the
/// frustum traversal takes; wider packets go lane by lane. Measured in benches/traverse.rs: on
/// the 1M-triangle scene, pixel blocks whose lanes aim at different VPLs (slopes spanning ~1)
/// were ~1000× slower through a 45° frustum than as single rays.
const MAX_SLOPE_SPAN: f32 = 0.2;

/// Camera packets test their lanes against an inner child whose thinnest side is narrower than
/// this multiple of the frustum's width where the child is entered (see [`Cull::lane_tests`]):
/// thin boxes (Sponza's walls, columns and drapes, seen at a slant) pass the frustum test while
/// most lanes miss them. Measured on the traverse bench's primary rays, 1 thread, Zen 4
/// (Mrays/s, no lane tests → this rule): Sponza 8-wide 9.3 → 10.7 and 16-wide 15.0 → 17.0,
/// Igea within noise (15.2 → 15.1, 21.3 → 21.1). Testing every inner child gave Sponza a little
/// more (11.4, 17.3) but cost Igea 3–4 %; a rule on the widest side gave no gain.
const LANE_TEST_WIDTH: f32 = 32.0;

/// The packet's frustum as planes through a common apex (the shared origin of primary rays, or
/// the shared end point of shadow rays traced backwards): four side planes bounding the lanes'
/// directions around a central axis `c`, and the plane through the apex normal to `c` (Reshetov,
/// Soupikov & Hurley 2005; Benthin & Wald 2009). A child is culled when its box lies entirely
/// outside one plane, or starts (along `c`) beyond the culling distance. With 8 children per
/// SIMD register this costs about as much as one single-ray node test, whatever the direction
/// components (unlike interval arithmetic on 1/d, which degenerates near zero components).
/// Conservative: planes are widened by the rounding of their construction and by the spread of
/// the lanes' apexes.
struct PlaneFrustum {
    apex: [f32; 3],
    /// Side planes `n·(p − apex) ≥ −eps`: per plane, per axis the `bounds` row of the box vertex
    /// farthest along n, and n.
    rows: [[usize; 3]; 4],
    normals: [[f32; 3]; 4],
    eps: [f32; 4],
    /// Central axis: rows of the vertex nearest along c, c itself.
    c_rows: [usize; 3],
    c: [f32; 3],
    /// Margin of the distance along c (apex spread and rounding).
    c_eps: f32,
    /// The lanes do not start at one apex (shadow rays traced backwards from their end point,
    /// or rays from spread origins): inner children that pass the frustum also get the exact
    /// per-lane test, and carry only the lanes that hit them. Such a frustum is loose between
    /// its rays (the rays of a 4×2 block leave from different spheres of the 1M-triangle
    /// scene); the lane tests took its shadow packets from 18.3 to 27.7 Mrays/s (occlusion, 2
    /// threads) and Igea's stayed within noise. From one apex (camera rays) the frustum is
    /// tight and the extra tests cost 7 % on Igea's primary rays, so they are skipped there.
    lane_tests: bool,
    /// Widest slope span of the lanes (the frustum's width per unit distance along c).
    span: f32,
}

impl PlaneFrustum {
    /// The frustum of unit directions `dir` (lanes in `active`) from apexes within `spread` of
    /// `apex`; None when the directions do not fit in a narrow cone (see [`MAX_SLOPE_SPAN`]).
    fn new<F: Lanes>(apex: Vec3, spread: f32, dir: &Vec3x<F>, active: u32) -> Option<Self> {
        let sum = Vec3::new(dir.x.sum_lanes(active), dir.y.sum_lanes(active), dir.z.sum_lanes(active));
        let c = sum.try_normalize()?;
        let (u, v) = c.any_orthonormal_pair();
        let (du, dv, dc) = (dir.dot(&Vec3x::splat(u)), dir.dot(&Vec3x::splat(v)), dir.dot(&Vec3x::splat(c)));
        if dc.min_lanes(active) < 0.7 {
            return None;
        }
        let (a, b) = (du / dc, dv / dc);
        let slopes = [a.min_lanes(active), a.max_lanes(active), b.min_lanes(active), b.max_lanes(active)];
        Self::from_slopes(apex, spread, [u, v, c], slopes)
    }

    /// The frustum of the directions `c + a·u + b·v` with slopes `a` in `[a_lo, a_hi]` and `b`
    /// in `[b_lo, b_hi]` (`[u, v, c]` orthonormal up to rounding), from apexes within `spread` of
    /// `apex`; None when it is too wide (see [`MAX_SLOPE_SPAN`]).
    fn from_slopes(apex: Vec3, spread: f32, [u, v, c]: [Vec3; 3], [a_lo, a_hi, b_lo, b_hi]: [f32; 4]) -> Option<Self> {
        // A wide cone culls little and the traversal would visit most of the tree: beyond
        // ~11° (slopes spanning more than 0.2) the lanes are traced one by one instead.
        if !((a_hi - a_lo).max(b_hi - b_lo) <= MAX_SLOPE_SPAN) {
            return None;
        }
        // Widen the slopes for the rounding of their computation (1e-4 rad: at the far side of
        // the scene, 10⁻⁴ of its size).
        let widen = |x: f32, s: f32| x + s * 1e-4 * (1.0 + x.abs());
        let (a_lo, a_hi, b_lo, b_hi) = (widen(a_lo, -1.0), widen(a_hi, 1.0), widen(b_lo, -1.0), widen(b_hi, 1.0));
        let normals = [u - c * a_lo, c * a_hi - u, v - c * b_lo, c * b_hi - v];
        let margin = spread + 4.0;
        let row = |n: Vec3, axis: usize| 2 * axis + (n[axis] >= 0.0) as usize;
        Some(PlaneFrustum {
            apex: apex.to_array(),
            rows: normals.map(|n| [row(n, 0), row(n, 1), row(n, 2)]),
            normals: normals.map(|n| n.to_array()),
            eps: normals.map(|n| -margin * n.length()),
            c_rows: [0, 1, 2].map(|axis| 2 * axis + (c[axis] < 0.0) as usize),
            c: c.to_array(),
            c_eps: margin,
            lane_tests: spread > 0.0,
            span: (a_hi - a_lo).max(b_hi - b_lo),
        })
    }
}

impl Cull for PlaneFrustum {
    #[inline(always)]
    fn test(&self, bounds: &[[f32; 8]; 6], t_cull: f32) -> (F8, u32) {
        // Box corners relative to the apex: rows 2·axis (min) and 2·axis + 1 (max).
        let rel: [F8; 6] = std::array::from_fn(|row| F8::from_array(bounds[row]) - F8::splat(self.apex[row / 2]));
        let mut inside = F8::splat(0.0).le(F8::splat(0.0));
        for k in 0..4 {
            let [rx, ry, rz] = self.rows[k];
            let [nx, ny, nz] = self.normals[k].map(F8::splat);
            let dist = rel[rx] * nx + rel[ry] * ny + rel[rz] * nz;
            inside = inside.and(dist.ge(F8::splat(self.eps[k])));
        }
        let [cx, cy, cz] = self.c_rows;
        let c = self.c.map(F8::splat);
        let along = rel[cx] * c[0] + rel[cy] * c[1] + rel[cz] * c[2] - F8::splat(self.c_eps);
        // Boxes entirely behind the apex: their farthest corner along c is behind it.
        let back = rel[cx ^ 1] * c[0] + rel[cy ^ 1] * c[1] + rel[cz ^ 1] * c[2];
        let t_near = along.vmax(F8::splat(0.0));
        let hit = inside.and(back.ge(F8::splat(-self.c_eps))).and(t_near.le(F8::splat(t_cull)));
        (t_near, hit.bitmask())
    }

    #[inline(always)]
    fn lane_tests(&self, bounds: &[[f32; 8]; 6], t_near: F8) -> u32 {
        if self.lane_tests {
            return 0xff;
        }
        // From one apex: the boxes that are thin next to the frustum where they are entered
        // (lanes may pass beside them).
        let extent = |a: usize| F8::from_array(bounds[2 * a + 1]) - F8::from_array(bounds[2 * a]);
        let size = extent(0).vmin(extent(1)).vmin(extent(2));
        size.lt(t_near * F8::splat(self.span * LANE_TEST_WIDTH)).bitmask()
    }
}

/// What a packet's rays are known to share: one origin `apex` (world space), and directions
/// `c + a·u + b·v` (`basis` = `[u, v, c]`, orthonormal) with slopes within `slopes` = `[a_lo,
/// a_hi, b_lo, b_hi]` (before rounding, which the frustum allows for). A pinhole camera's rays
/// through a block of pixels ([`crate::scene::Camera::raster_slopes`]).
#[derive(Clone, Copy, Debug)]
pub struct PacketView {
    /// The rays' common origin.
    pub apex: Vec3,
    /// `[u, v, c]`.
    pub basis: [Vec3; 3],
    /// `[a_lo, a_hi, b_lo, b_hi]`.
    pub slopes: [f32; 4],
}

/// A packet in the canonical frame with the per-lane constants of the box and triangle tests.
struct CanonicalPacket<F: Lanes> {
    origin: Vec3x<F>,
    dir: Vec3x<F>,
    rdir: Vec3x<F>,
    /// Per axis, the lanes whose reciprocal direction is negative (near plane = max).
    negative: [F; 3],
    /// Canonical t_max (−∞ in inactive lanes).
    t_max: F,
    to_param: F,
    shear: ShearPacket<F>,
    active: u32,
}

impl<F: Lanes> CanonicalPacket<F> {
    /// Maps the lanes to the canonical frame on all lanes at once: lane for lane exactly
    /// [`Accel::canonical`] (same operations in the same order, correctly rounded division
    /// and square root), so a lane is the very ray a single-ray query traces.
    #[inline]
    fn new(accel: &Accel, packet: &RayPacket<F>) -> Self {
        let (o, d) = (&packet.origin, &packet.dir);
        let zero = F::splat(0.0);
        let len = (d.x * d.x + d.y * d.y + d.z * d.z).sqrt();
        let valid = F::mask_from_bits(packet.active)
            .and(len.gt(zero))
            .and(len.finite())
            .and(packet.t_max.gt(zero))
            .and(o.x.finite())
            .and(o.y.finite())
            .and(o.z.finite());
        let active = valid.bitmask();
        let (frame, scale) = (accel.frame, F::splat(accel.frame.scale));
        let to_param = F::splat(1.0) / (len * scale);
        // Inactive lanes: origin 0, direction +x, empty interval.
        let idle = |v: F, x: f32| valid.select(v, F::splat(x));
        let origin = Vec3x {
            x: idle((o.x - F::splat(frame.center.x)) * scale, 0.0),
            y: idle((o.y - F::splat(frame.center.y)) * scale, 0.0),
            z: idle((o.z - F::splat(frame.center.z)) * scale, 0.0),
        };
        let dir = Vec3x { x: idle(d.x / len, 1.0), y: idle(d.y / len, 0.0), z: idle(d.z / len, 0.0) };
        let rdir = Vec3x { x: F::splat(1.0) / dir.x, y: F::splat(1.0) / dir.y, z: F::splat(1.0) / dir.z };
        CanonicalPacket {
            negative: [rdir.x.lt(zero), rdir.y.lt(zero), rdir.z.lt(zero)],
            t_max: idle(packet.t_max / to_param, f32::NEG_INFINITY),
            to_param: idle(to_param, 0.0),
            shear: ShearPacket::from_lanes(&origin, &dir, active),
            active,
            origin,
            dir,
            rdir,
        }
    }

    /// The octant of the sum of the lanes' directions.
    #[inline]
    fn octant(&self) -> usize {
        let a = self.active;
        octant(Vec3::new(self.dir.x.sum_lanes(a), self.dir.y.sum_lanes(a), self.dir.z.sum_lanes(a)))
    }

    /// Lane `i` as a single canonical ray.
    #[inline]
    fn ray(&self, i: usize) -> CanonicalRay {
        CanonicalRay {
            origin: self.origin.lane(i),
            dir: self.dir.lane(i),
            t_max: self.t_max.lane(i),
            to_param: self.to_param.lane(i),
        }
    }

    /// Entry distances of the lanes into child `slot` of `node` and the mask of lanes that
    /// enter it at or before their `t_cull` (lane for lane [`super::single::box_hit_scalar`]).
    #[inline(always)]
    fn test_child<const W: usize>(&self, node: &Node<W>, slot: usize, t_cull: F) -> (F, F) {
        let b = &node.bounds;
        let slab = |axis: usize, o: F, r: F| {
            let lo = (F::splat(b[2 * axis][slot]) - o) * r;
            let hi = (F::splat(b[2 * axis + 1][slot]) - o) * r;
            let neg = self.negative[axis];
            (neg.select(hi, lo), neg.select(lo, hi))
        };
        let (nx, fx) = slab(0, self.origin.x, self.rdir.x);
        let (ny, fy) = slab(1, self.origin.y, self.rdir.y);
        let (nz, fz) = slab(2, self.origin.z, self.rdir.z);
        // Slab first: a NaN slab (ray in the plane) is ignored.
        let t_near = nx.vmax(ny.vmax(nz.vmax(F::splat(0.0))));
        let t_far = fx.vmin(fy.vmin(fz.vmin(F::splat(f32::INFINITY))));
        (t_near, t_near.le((t_far * F::splat(ROBUST)).vmin(t_cull)))
    }
}

/// Capacity of the array stacks of the lane-wise packet traversals ([`lanewise`]).
const STACK: usize = 128;

/// Array entries of the frustum traversals' stacks (beyond them a traversal spills into the
/// heap): a 128-entry array was zeroed for every packet, 1.5 KB of stores per 8 rays.
const SPILL_AT: usize = 32;

impl Accel {
    /// Closest hits of the rays of `packet` (world space, as [`Accel::intersect`] per lane).
    pub fn intersect_packet<F: Lanes>(&self, packet: &RayPacket<F>) -> PacketHits<F> {
        self.intersect_packet_in(packet, None)
    }

    /// [`Accel::intersect_packet`] for rays known to lie in `view` (camera rays of a pixel
    /// block): its frustum is built from the view's bounds instead of from the lanes' directions
    /// (which took reductions across lanes, a normalisation and divisions per packet). The same
    /// hits: the frustum only culls, conservatively.
    pub fn intersect_packet_in<F: Lanes>(&self, packet: &RayPacket<F>, view: Option<&PacketView>) -> PacketHits<F> {
        let p = CanonicalPacket::new(self, packet);
        let frustum = match view {
            Some(v) if p.active != 0 => {
                let f = self.frame;
                PlaneFrustum::from_slopes((v.apex - f.center) * f.scale, 0.0, v.basis, v.slopes)
            }
            _ => p.forward_frustum(),
        };
        let (hit, t, tri_bits, b1, b2) = match frustum {
            None => closest_lanes(&self.wide, &p),
            Some(f) => closest_frustum(&self.wide, &p, &f, &mut SpillStack::<_, SPILL_AT>::new((0, 0.0, 0))),
        };
        PacketHits { hit, t: t * p.to_param, tri_bits, b1, b2 }
    }

    /// Occlusion of the rays of `packet` (as [`Accel::occluded`] per lane): bit i set when
    /// lane i is blocked.
    pub fn occluded_packet<F: Lanes>(&self, packet: &RayPacket<F>) -> u32 {
        let p = CanonicalPacket::new(self, packet);
        match p.segment_frustum() {
            None => occluded_lanes(&self.wide, &p),
            Some((f, length)) => {
                occluded_frustum(&self.wide, &p, &f, length, &mut SpillStack::<_, SPILL_AT>::new((0, 0.0, 0)))
            }
        }
    }

    /// Occlusion of the rays of `packet` traced one by one, after setting them all up at once
    /// (canonical frame, shear and reciprocal directions on all lanes together): bit i set when
    /// lane i is blocked, exactly [`Accel::occluded_cached`] per lane with `hints[i]` as lane
    /// i's shadow cache. For rays that go different ways (one pixel towards several VPLs), where
    /// a packet traversal would not pay.
    /// `hints` needs an entry for every lane up to the highest active one.
    pub fn occluded_lanes_cached<F: Lanes>(&self, packet: &RayPacket<F>, hints: &mut [u32]) -> u32 {
        debug_assert!(hints.len() >= 32 - packet.active.leading_zeros() as usize);
        occluded_each(&self.wide, &CanonicalPacket::new(self, packet), hints)
    }
}

impl<F: Lanes> CanonicalPacket<F> {
    /// Centre and radius of the box around the points `v` of the active lanes.
    #[inline]
    fn bounds_of(&self, v: &Vec3x<F>) -> (Vec3, f32) {
        let a = self.active;
        let lo = Vec3::new(v.x.min_lanes(a), v.y.min_lanes(a), v.z.min_lanes(a));
        let hi = Vec3::new(v.x.max_lanes(a), v.y.max_lanes(a), v.z.max_lanes(a));
        (0.5 * (lo + hi), 0.5 * (hi - lo).length())
    }

    /// The frustum of the rays from their origins (None: too incoherent).
    #[inline]
    fn forward_frustum(&self) -> Option<PlaneFrustum> {
        let (apex, spread) = self.bounds_of(&self.origin);
        PlaneFrustum::new(apex, spread, &self.dir, self.active)
    }

    /// The frustum bounding the rays' segments (0, t_max] for occlusion, and the distance its
    /// tests cull at: from the origins (culling at each lane's t_max), or, when the segments'
    /// end points are closer together than their origins (shadow rays to one light or VPL),
    /// traced backwards from the end points (Some(largest segment length)). The backward
    /// frustum contains every point of every segment, so it culls conservatively; exact tests
    /// stay in the forward direction. None: too incoherent.
    #[inline]
    fn segment_frustum(&self) -> Option<(PlaneFrustum, Option<f32>)> {
        let a = self.active;
        let (apex, spread) = self.bounds_of(&self.origin);
        if a != 0 && self.t_max.finite().bitmask() & a == a {
            let o = &self.origin;
            let t = self.t_max;
            let end = Vec3x { x: o.x + self.dir.x * t, y: o.y + self.dir.y * t, z: o.z + self.dir.z * t };
            let (end_apex, end_spread) = self.bounds_of(&end);
            if end_spread < spread {
                // The end points carry the rounding of o + d·t: widen by that.
                let rounding = (end_apex.abs().max_element() + end_spread) * (1.0 / 1_048_576.0) + CULL_SLACK;
                let zero = F::splat(0.0);
                let back = Vec3x { x: zero - self.dir.x, y: zero - self.dir.y, z: zero - self.dir.z };
                let length = t.max_lanes(a) * ROBUST + CULL_SLACK;
                return PlaneFrustum::new(end_apex, end_spread + rounding, &back, a).map(|f| (f, Some(length)));
            }
        }
        PlaneFrustum::new(apex, spread, &self.dir, a).map(|f| (f, None))
    }

    /// Per-lane culling distances.
    #[inline(always)]
    fn cull(t: F) -> F {
        t * F::splat(ROBUST) + F::splat(CULL_SLACK)
    }
}

/// A traversal stack of (reference, entry distance, lanes).
trait Stack3 {
    fn push(&mut self, e: (u32, f32, u32));
    fn pop(&mut self) -> Option<(u32, f32, u32)>;
}

impl<const N: usize> Stack3 for SpillStack<(u32, f32, u32), N> {
    #[inline(always)]
    fn push(&mut self, e: (u32, f32, u32)) {
        self.push_item(e);
    }
    #[inline(always)]
    fn pop(&mut self) -> Option<(u32, f32, u32)> {
        self.pop_item()
    }
}

/// Frustum test of the children of `node` for the lanes `alive` (those that entered it); leaf
/// children, and every child when [`Cull::lane_tests`] says so, also get the exact per-lane
/// test and keep only the lanes that pass it. Pushes the hit children far to near and returns
/// the nearest, or None; for any-hit queries (`any_hit`) leaves come before inner nodes (a
/// leaf is tested at once and its large triangles block most rays that reach it; see
/// `single::descend_any`).
#[inline(always)]
fn descend_frustum<F: Lanes>(
    bvh: &WideBvh<8>,
    p: &CanonicalPacket<F>,
    frustum: &impl Cull,
    node: &Node<8>,
    cull_max: f32,
    t_cull: F,
    alive: u32,
    stack: &mut impl Stack3,
    any_hit: bool,
) -> Option<(u32, u32)> {
    let (t_near, mut mask) = frustum.test(&node.bounds, cull_max);
    if mask == 0 {
        return None;
    }
    let exact = frustum.lane_tests(&node.bounds, t_near);
    let t = t_near.to_array();
    let mut hits = [(0u32, 0.0f32, 0u32); 8];
    let mut n = 0;
    while mask != 0 {
        let slot = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        let c = node.child[slot];
        let lanes = if exact >> slot & 1 != 0 || c & LEAF_BIT != 0 {
            let (_, m) = p.test_child(node, slot, t_cull);
            m.bitmask() & alive
        } else {
            alive
        };
        if lanes != 0 {
            prefetch_ref(bvh, c);
            hits[n] = (c, t[slot], lanes);
            n += 1;
        }
    }
    if n == 0 {
        return None;
    }
    // Far to near, so that the nearest is popped first (any-hit: inner nodes below leaves).
    let hits = &mut hits[..n];
    let key = |h: &(u32, f32, u32)| {
        let inner = any_hit && h.0 & LEAF_BIT == 0;
        (inner, h.1)
    };
    for i in 1..hits.len() {
        let mut j = i;
        while j > 0 && key(&hits[j - 1]) < key(&hits[j]) {
            hits.swap(j - 1, j);
            j -= 1;
        }
    }
    for &h in &hits[..n - 1] {
        stack.push(h);
    }
    Some((hits[n - 1].0, hits[n - 1].2))
}

/// Closest hits found so far, lane by lane.
struct Closest<F: Lanes> {
    t: F,
    id: F,
    b1: F,
    b2: F,
}

impl<F: Lanes> Closest<F> {
    /// Tests the `count` triangles of a leaf block against the lanes of `mask`, keeping nearer
    /// hits (equal t: the smaller scene index wins, as for single rays); returns the lanes whose
    /// hit changed.
    #[inline(always)]
    fn leaf(&mut self, p: &CanonicalPacket<F>, block: &TriBlock, count: usize, mask: F) -> u32 {
        let mut changed = 0u32;
        for k in 0..count {
            let corner = |c: usize| Vec3A::new(block.v[3 * c][k], block.v[3 * c + 1][k], block.v[3 * c + 2][k]);
            let h = intersect_packet(&p.shear, corner(0), corner(1), corner(2), self.t, mask);
            if h.mask.bitmask() == 0 {
                continue;
            }
            let mut better = h.mask.and(h.t.lt(self.t));
            let ties = h.mask.and(h.t.eq(self.t)).bitmask();
            if ties != 0 {
                let tie_wins = (0..F::LANES)
                    .filter(|&i| ties >> i & 1 != 0 && block.id[k] < self.id.lane_bits(i))
                    .fold(0u32, |m, i| m | 1 << i);
                better = better.or(F::mask_from_bits(tie_wins));
            }
            let bits = better.bitmask();
            if bits != 0 {
                self.t = better.select(h.t, self.t);
                self.id = better.select(F::splat_bits(block.id[k]), self.id);
                self.b1 = better.select(h.b1, self.b1);
                self.b2 = better.select(h.b2, self.b2);
                changed |= bits;
            }
        }
        changed
    }
}

/// Closest hits of a coherent packet: frustum traversal, exact lane tests at leaves (and at
/// inner nodes for frusta without a common apex).
#[inline(always)]
fn closest_frustum<F: Lanes>(
    bvh: &WideBvh<8>,
    p: &CanonicalPacket<F>,
    frustum: &impl Cull,
    stack: &mut impl Stack3,
) -> (u32, F, F, F, F) {
    let mut best = Closest { t: p.t_max, id: F::splat_bits(EMPTY), b1: F::splat(0.0), b2: F::splat(0.0) };
    let mut found = 0u32;
    let mut t_cull = CanonicalPacket::<F>::cull(best.t);
    let mut cull_max = t_cull.max_lanes(p.active);
    let mut cur = (p.active != 0).then_some((bvh.root, p.active));
    loop {
        while let Some((r, lanes)) = cur {
            if r & LEAF_BIT == 0 {
                cur = descend_frustum(bvh, p, frustum, &bvh.nodes[r as usize], cull_max, t_cull, lanes, stack, false);
                continue;
            }
            let (b, count) = leaf_parts(r);
            let block = &bvh.blocks[b];
            let bits = best.leaf(p, block, count, F::mask_from_bits(lanes));
            found |= bits;
            if bits != 0 {
                t_cull = CanonicalPacket::<F>::cull(best.t);
                cull_max = t_cull.max_lanes(p.active);
            }
            cur = None;
        }
        loop {
            match stack.pop() {
                None => return (found, best.t, best.id, best.b1, best.b2),
                Some((r, t, lanes)) if t <= cull_max => {
                    cur = Some((r, lanes));
                    break;
                }
                Some(_) => {}
            }
        }
    }
}

/// Occlusion of a coherent packet: frustum traversal, exact lane tests at leaves (and at inner
/// nodes for frusta without a common apex); blocked lanes drop out and the traversal ends when
/// all are blocked.
#[inline(always)]
fn occluded_frustum<F: Lanes>(
    bvh: &WideBvh<8>,
    p: &CanonicalPacket<F>,
    frustum: &impl Cull,
    reversed_length: Option<f32>,
    stack: &mut impl Stack3,
) -> u32 {
    let mut t_max = p.t_max;
    let mut t_cull = CanonicalPacket::<F>::cull(t_max);
    let mut alive = p.active;
    // The frustum's culling distance: the lanes' (shrinking as lanes are blocked), or the
    // reversed frustum's fixed length.
    let frustum_cull = |t_cull: F, alive: u32| reversed_length.unwrap_or_else(|| t_cull.max_lanes(alive));
    let mut cull_max = frustum_cull(t_cull, alive);
    let mut cur = (alive != 0).then_some((bvh.root, alive));
    loop {
        while let Some((r, lanes)) = cur {
            let lanes = lanes & alive;
            if r & LEAF_BIT == 0 {
                cur = descend_frustum(bvh, p, frustum, &bvh.nodes[r as usize], cull_max, t_cull, lanes, stack, true);
                continue;
            }
            let (b, count) = leaf_parts(r);
            let block = &bvh.blocks[b];
            let mut lanes = lanes;
            for k in 0..count {
                if lanes == 0 {
                    break;
                }
                let corner = |c: usize| Vec3A::new(block.v[3 * c][k], block.v[3 * c + 1][k], block.v[3 * c + 2][k]);
                let h = intersect_packet(&p.shear, corner(0), corner(1), corner(2), t_max, F::mask_from_bits(lanes));
                let now = h.mask.and(h.t.lt(t_max));
                let bits = now.bitmask();
                if bits != 0 {
                    alive &= !bits;
                    if alive == 0 {
                        return p.active;
                    }
                    lanes &= !bits;
                    t_max = now.select(F::splat(f32::NEG_INFINITY), t_max);
                    t_cull = now.select(F::splat(f32::NEG_INFINITY), t_cull);
                    cull_max = frustum_cull(t_cull, alive);
                }
            }
            cur = None;
        }
        loop {
            match stack.pop() {
                None => return p.active & !alive,
                Some((r, t, lanes)) if t <= cull_max && lanes & alive != 0 => {
                    cur = Some((r, lanes & alive));
                    break;
                }
                Some(_) => {}
            }
        }
    }
}

/// Closest hits of an incoherent packet, lane by lane with the single-ray traversal.
fn closest_lanes<F: Lanes>(bvh: &WideBvh<8>, p: &CanonicalPacket<F>) -> (u32, F, F, F, F) {
    let mut hits = [(f32::INFINITY, EMPTY, 0.0f32, 0.0f32); 16];
    let mut found = 0;
    for (i, h) in hits.iter_mut().enumerate().take(F::LANES) {
        if p.active >> i & 1 != 0
            && let Some((t, tri, b1, b2)) = closest(bvh, &p.ray(i))
        {
            *h = (t, tri, b1, b2);
            found |= 1 << i;
        }
    }
    (
        found,
        F::from_fn(|i| hits[i].0),
        F::from_fn(|i| f32::from_bits(hits[i].1)),
        F::from_fn(|i| hits[i].2),
        F::from_fn(|i| hits[i].3),
    )
}

/// Occlusion of an incoherent packet, lane by lane with the single-ray traversal.
fn occluded_lanes<F: Lanes>(bvh: &WideBvh<8>, p: &CanonicalPacket<F>) -> u32 {
    occluded_each(bvh, p, &mut [NO_OCCLUDER; 16])
}

/// Occlusion of each active lane of `p` by the single-ray traversal, from the lane's set-up
/// (no divisions redone), `hints[i]` being lane i's shadow cache.
fn occluded_each<F: Lanes>(bvh: &WideBvh<8>, p: &CanonicalPacket<F>, hints: &mut [u32]) -> u32 {
    let mut blocked = 0;
    let mut m = p.active;
    // The lanes' values unpacked once (read from the packet lane by lane, each went through a
    // store and a reload per lane).
    let shear = p.shear.lanes();
    let [ox, oy, oz, rx, ry, rz] = [p.origin.x, p.origin.y, p.origin.z, p.rdir.x, p.rdir.y, p.rdir.z].map(F::to_array);
    let t_max = p.t_max.to_array();
    while m != 0 {
        let i = m.trailing_zeros() as usize;
        m &= m - 1;
        let origin = Vec3::new(ox.as_ref()[i], oy.as_ref()[i], oz.as_ref()[i]);
        let rdir = || [rx.as_ref()[i], ry.as_ref()[i], rz.as_ref()[i]];
        if occluded_from_parts(bvh, shear.lane(i, origin), origin, t_max.as_ref()[i], &mut hints[i], rdir) {
            blocked |= 1 << i;
        }
    }
    blocked
}
