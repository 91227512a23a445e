//! Single-ray queries. [`Accel::intersect`] / [`Accel::occluded`] traverse our 8-wide BVH
//! ([`super::wide`]) testing all 8 child boxes with one SIMD operation per plane and the (up
//! to 4) triangles of a leaf with one 4-lane watertight test; [`Accel::intersect_obvhs`] /
//! [`Accel::occluded_obvhs`] traverse obvhs's CWBVH (the baseline), with the same triangle test.
//!
//! Box test: Williams et al.'s slab test (2005) with the near plane chosen by the direction's
//! sign and distances `(plane − o)·(1/d)` with IEEE reciprocals. A zero direction component
//! gives ±∞ (origin off the plane) or NaN (origin exactly on it); slab distances are folded
//! in as `slab.vmax(acc)` / `slab.vmin(acc)`, which ignore a NaN slab, so a ray lying in a
//! box face counts as inside that slab (closed boxes). The far distance is scaled by [`ROBUST`]
//! so that rounding never culls a box the ray touches (Ize 2013, "Robust BVH Ray Traversal").
//! Hit children are pushed and sorted by entry distance (nearest on top).
//!
//! Culling against the closest hit so far uses [`cull_distance`]: a relative *and* an absolute
//! margin, because the watertight test's t of a large triangle hit close to the origin carries
//! an absolute error of a few ulps of the scene's coordinates. Without the margin, a box
//! holding a hit a hair closer than the current one could be culled, and the answer would
//! depend on the traversal order (single rays and packets disagreed on 0.6 % of grazing rays).
//!
//! Ties: when two triangles report the same t the smaller scene index wins, in every traversal,
//! so the result does not depend on traversal order (packets and single rays agree).

use glam::Vec3;
use obvhs::ray::{Ray as BvhRay, RayHit};

use super::triangle::{ShearedRay, intersect, intersect_block};
use super::wide::{EMPTY, LEAF_BIT, WideBvh, leaf_parts};
use super::{Accel, Hit};
use crate::scene::{Scene, SurfacePoint};
use crate::simd::{F4, F8, Lanes};

/// Factor on far distances that makes box tests conservative: 1 + 2⁻²⁰, above Ize's 1 + 2γ₃
/// (≈ 1 + 3.6·10⁻⁷), with room for the rounding of the triangle test's t.
pub const ROBUST: f32 = 1.0 + 1.0 / 1_048_576.0;

/// Absolute culling margin in canonical units: 16 ulps of the largest canonical coordinate
/// (2¹⁹), 10⁻⁶ of the scene's diagonal.
pub const CULL_SLACK: f32 = 1.0;

/// Boxes entered beyond this distance cannot hold a hit closer than `best_t`.
#[inline(always)]
pub fn cull_distance(best_t: f32) -> f32 {
    best_t * ROBUST + CULL_SLACK
}

/// A world-space ray in the canonical frame: origin, unit direction, t_max, and the factor
/// converting canonical distances back to the caller's ray parameter.
#[derive(Clone, Copy, Debug)]
pub struct CanonicalRay {
    /// Origin (canonical frame).
    pub origin: Vec3,
    /// Unit direction.
    pub dir: Vec3,
    /// End of the interval (canonical units).
    pub t_max: f32,
    /// Canonical distance → caller's ray parameter.
    pub to_param: f32,
}

impl Accel {
    /// Maps a world ray to the canonical frame; `None` for rays that cannot hit anything
    /// (zero or non-finite direction, non-finite origin, t_max ≤ 0 or NaN).
    #[inline]
    pub fn canonical(&self, origin: Vec3, dir: Vec3, t_max: f32) -> Option<CanonicalRay> {
        let len = dir.length();
        if !(len > 0.0) || !(t_max > 0.0) || !len.is_finite() || !origin.is_finite() {
            return None;
        }
        let to_param = 1.0 / (len * self.frame.scale);
        let t_max = if t_max.is_finite() { t_max / to_param } else { f32::INFINITY };
        Some(CanonicalRay { origin: self.frame.point(origin), dir: dir / len, t_max, to_param })
    }

    /// The closest hit along `origin + t·dir` for t in (0, t_max] (world space; `dir` need not
    /// be normalised, `t` is in units of its length).
    #[inline]
    pub fn intersect(&self, origin: Vec3, dir: Vec3, t_max: f32) -> Option<Hit> {
        let ray = self.canonical(origin, dir, t_max)?;
        let (t, tri, b1, b2) = closest(&self.wide, &ray)?;
        Some(Hit { t: t * ray.to_param, tri, b1, b2 })
    }

    /// True when something blocks `origin + t·dir` for t in (0, t_max).
    #[inline]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        self.occluded_cached(origin, dir, t_max, &mut NO_OCCLUDER.clone())
    }

    /// [`Accel::occluded`] with an occluder cache (a shadow cache): `hint` names a leaf that
    /// blocked a similar ray — the previous shadow ray to the same VPL from a nearby pixel — and
    /// is tested before the traversal; a traversal that finds an occluder leaves its leaf in
    /// `hint` ([`NO_OCCLUDER`]: none yet). The answer is exactly `occluded`'s: a hit in the
    /// hinted leaf is a hit, and a miss there falls back to the full traversal.
    #[inline]
    pub fn occluded_cached(&self, origin: Vec3, dir: Vec3, t_max: f32, hint: &mut u32) -> bool {
        self.canonical(origin, dir, t_max).is_some_and(|ray| occluded(&self.wide, &ray, hint))
    }

    /// [`Accel::intersect`] through obvhs's own CWBVH traversal (the benchmark baseline).
    /// Identical results except for equal-t ties and geometry within obvhs's node clip
    /// distance (10⁻¹⁰ of the scene size) of the origin.
    ///
    /// # Panics
    /// When the structure was built without the baseline (use [`Accel::build_with_obvhs`]).
    pub fn intersect_obvhs(&self, origin: Vec3, dir: Vec3, t_max: f32) -> Option<Hit> {
        let o = self.obvhs.as_ref().expect("intersect_obvhs needs Accel::build_with_obvhs");
        let ray = self.canonical(origin, dir, t_max)?;
        let sheared = ShearedRay::new(ray.origin, ray.dir);
        let bvh_ray = BvhRay::new(ray.origin.into(), ray.dir.into(), 0.0, ray.t_max);
        let mut hit = RayHit::none();
        let mut best = (0.0f32, 0.0f32);
        let mut best_t = ray.t_max;
        let found = o.bvh.ray_traverse(bvh_ray, &mut hit, |r, prim| {
            let [p0, p1, p2] = o.tris[prim];
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
        Some(Hit { t: hit.t * ray.to_param, tri: o.prim_to_tri[hit.primitive_id as usize], b1: best.0, b2: best.1 })
    }

    /// [`Accel::occluded`] through obvhs's own CWBVH traversal (the benchmark baseline).
    ///
    /// # Panics
    /// When the structure was built without the baseline (use [`Accel::build_with_obvhs`]).
    pub fn occluded_obvhs(&self, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        let o = self.obvhs.as_ref().expect("occluded_obvhs needs Accel::build_with_obvhs");
        let Some(ray) = self.canonical(origin, dir, t_max) else { return false };
        let sheared = ShearedRay::new(ray.origin, ray.dir);
        let bvh_ray = BvhRay::new(ray.origin.into(), ray.dir.into(), 0.0, ray.t_max);
        !o.bvh.ray_traverse_miss(bvh_ray, |_, prim| {
            let [p0, p1, p2] = o.tris[prim];
            match intersect(&sheared, p0, p1, p2, 0.0, ray.t_max) {
                Some(h) if h.t < ray.t_max => h.t,
                _ => f32::INFINITY,
            }
        })
    }

    /// Visibility between two surface points (offsetting both ends, see the module doc).
    pub fn visible(&self, scene: &Scene, a: &SurfacePoint, b: &SurfacePoint) -> bool {
        let (oa, ob) = super::shadow_segment(scene, a, b);
        !self.occluded(oa, ob - oa, super::SHADOW_T_MAX)
    }
}

/// A traversal stack of (reference, entry distance).
trait Stack {
    fn push(&mut self, r: u32, t: f32);
    fn pop(&mut self) -> Option<(u32, f32)>;
    /// Sorts the top `n` entries so that the nearest is on top.
    fn sort_top(&mut self, n: usize);
}

/// A stack in a fixed array (no allocation), for trees whose [`WideBvh::stack_need`] fits.
struct ArrayStack<const N: usize> {
    items: [(u32, f32); N],
    len: usize,
}

impl<const N: usize> ArrayStack<N> {
    #[inline(always)]
    fn new() -> Self {
        ArrayStack { items: [(0, 0.0); N], len: 0 }
    }
}

#[inline(always)]
fn sort_desc(items: &mut [(u32, f32)]) {
    for i in 1..items.len() {
        let mut j = i;
        while j > 0 && items[j - 1].1 < items[j].1 {
            items.swap(j - 1, j);
            j -= 1;
        }
    }
}

impl<const N: usize> Stack for ArrayStack<N> {
    #[inline(always)]
    fn push(&mut self, r: u32, t: f32) {
        self.items[self.len] = (r, t);
        self.len += 1;
    }
    #[inline(always)]
    fn pop(&mut self) -> Option<(u32, f32)> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        Some(self.items[self.len])
    }
    #[inline(always)]
    fn sort_top(&mut self, n: usize) {
        sort_desc(&mut self.items[self.len - n..self.len]);
    }
}

/// A traversal stack whose first `N` entries live in an array and any further ones in a `Vec`.
/// The array is zeroed for every ray (safe Rust cannot leave it uninitialised), so it is kept
/// small: a tree's worst case ([`WideBvh::stack_need`], 7 entries per level) is rarely approached, and a
/// traversal that goes deeper spills into the heap instead of every ray zeroing room for it.
/// (Large trees zeroed a 128-entry, 1 KiB array per ray: 2.4 % of a Sponza frame, measured.)
pub(crate) struct SpillStack<T: Copy, const N: usize> {
    items: [T; N],
    len: usize,
    spill: Vec<T>,
}

impl<T: Copy, const N: usize> SpillStack<T, N> {
    /// An empty stack (`fill` initialises the array).
    #[inline(always)]
    pub(crate) fn new(fill: T) -> Self {
        SpillStack { items: [fill; N], len: 0, spill: Vec::new() }
    }

    #[inline(always)]
    pub(crate) fn push_item(&mut self, x: T) {
        if self.len < N {
            self.items[self.len] = x;
        } else {
            self.spill.push(x);
        }
        self.len += 1;
    }

    #[inline(always)]
    pub(crate) fn pop_item(&mut self) -> Option<T> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        if self.len < N { Some(self.items[self.len]) } else { self.spill.pop() }
    }
}

impl<const N: usize> Stack for SpillStack<(u32, f32), N> {
    #[inline(always)]
    fn push(&mut self, r: u32, t: f32) {
        self.push_item((r, t));
    }
    #[inline(always)]
    fn pop(&mut self) -> Option<(u32, f32)> {
        self.pop_item()
    }
    #[inline(always)]
    fn sort_top(&mut self, n: usize) {
        if self.len <= N {
            sort_desc(&mut self.items[self.len - n..self.len]);
        } else {
            // The top entries straddle the array and the spill: sort a copy (rare). A node has
            // at most eight children, so at most eight entries are sorted.
            debug_assert!(n <= 8);
            let mut top = [(0u32, 0.0f32); 8];
            let n = n.min(8);
            for slot in top[..n].iter_mut().rev() {
                *slot = self.pop_item().unwrap_or((0, 0.0));
            }
            sort_desc(&mut top[..n]);
            for &item in &top[..n] {
                self.push_item(item);
            }
        }
    }
}

/// Array entries of the single-ray stacks of trees that may need more than 16 (beyond them, a
/// traversal spills into the heap; see [`SpillStack`]).
const SPILL_AT: usize = 32;

/// The per-ray constants of the 8-wide box test.
struct BoxRay {
    o: [F8; 3],
    rdir: [F8; 3],
    /// `bounds` row of the near plane per axis (the far plane is the next row).
    near: [usize; 3],
}

impl BoxRay {
    #[inline(always)]
    fn new(origin: Vec3, dir: Vec3) -> Self {
        Self::from_rdir(origin, [1.0 / dir.x, 1.0 / dir.y, 1.0 / dir.z])
    }

    /// From the reciprocal direction `r` (`1 / dir`, as [`BoxRay::new`] computes it).
    #[inline(always)]
    fn from_rdir(origin: Vec3, r: [f32; 3]) -> Self {
        BoxRay {
            o: [F8::splat(origin.x), F8::splat(origin.y), F8::splat(origin.z)],
            rdir: r.map(F8::splat),
            near: [0, 1, 2].map(|a| 2 * a + (r[a] < 0.0) as usize),
        }
    }

    /// Entry distances of the 8 children and the mask of those entered at or before `t_cull`
    /// (and not behind the origin).
    #[inline(always)]
    fn test(&self, bounds: &[[f32; 8]; 6], t_cull: f32) -> (F8, u32) {
        let slab = |axis: usize, row: usize| (F8::from_array(bounds[row]) - self.o[axis]) * self.rdir[axis];
        let [nx, ny, nz] = self.near;
        // Slab first: a NaN slab (ray in the plane) is ignored.
        let t_near = slab(0, nx).vmax(slab(1, ny).vmax(slab(2, nz).vmax(F8::splat(0.0))));
        let t_far = slab(0, nx ^ 1).vmin(slab(1, ny ^ 1).vmin(slab(2, nz ^ 1).vmin(F8::splat(f32::INFINITY))));
        (t_near, t_near.le((t_far * F8::splat(ROBUST)).vmin(F8::splat(t_cull))).bitmask())
    }
}

/// Scalar twin of one lane of the box tests (single-ray and packet): the entry distance when
/// the ray meets the closed box [lo, hi] at or before `t_cull`.
pub fn box_hit_scalar(lo: Vec3, hi: Vec3, origin: Vec3, dir: Vec3, t_cull: f32) -> Option<f32> {
    let (mut t_near, mut t_far) = (0.0f32, f32::INFINITY);
    for axis in 0..3 {
        let r = 1.0 / dir[axis];
        let (n, f) = if r < 0.0 { (hi[axis], lo[axis]) } else { (lo[axis], hi[axis]) };
        // f32::max / min ignore NaN (ray in a face plane), as the SIMD code does.
        t_near = t_near.max((n - origin[axis]) * r);
        t_far = t_far.min((f - origin[axis]) * r);
    }
    (t_near <= (t_far * ROBUST).min(t_cull)).then_some(t_near)
}

/// Pushes the children of `mask` and returns the nearest to continue with (None: no child).
#[inline(always)]
fn descend<S: Stack>(bvh: &WideBvh<8>, stack: &mut S, child: &[u32; 8], t_near: F8, mask: u32) -> Option<u32> {
    match mask.count_ones() {
        0 => None,
        1 => Some(child[mask.trailing_zeros() as usize]),
        2 => {
            // The common case of two children: one on the stack, no sort.
            let t = t_near.to_array();
            let (i, j) = (mask.trailing_zeros() as usize, 31 - mask.leading_zeros() as usize);
            let (near, far) = if t[j] < t[i] { (j, i) } else { (i, j) };
            prefetch_ref(bvh, child[far]);
            stack.push(child[far], t[far]);
            Some(child[near])
        }
        n => {
            let t = t_near.to_array();
            let mut m = mask;
            while m != 0 {
                let i = m.trailing_zeros() as usize;
                m &= m - 1;
                prefetch_ref(bvh, child[i]);
                stack.push(child[i], t[i]);
            }
            stack.sort_top(n as usize);
            stack.pop().map(|(r, _)| r)
        }
    }
}

/// The mask of the slots of `child` that hold leaves (or are empty: the caller's hit masks never
/// contain empty slots).
#[inline(always)]
fn leaf_slots(child: &[u32; 8]) -> u32 {
    // The leaf flag is the sign bit.
    F8::from_array(child.map(f32::from_bits)).bitmask()
}

/// [`descend`] for any-hit queries: the leaves among the children first, then the inner nodes,
/// each in slot order, unsorted. A leaf is tested at once and ends the query when it blocks
/// the ray; the large triangles that sit in leaves near the root (a room's walls, a floor) block
/// most rays that reach them. (Inner nodes first, as the closest-hit order would take them,
/// traced the whole clutter of spheres before the wall behind them: bounce rays in the 1M
/// sphere field 4.1 Mrays/s against Embree's 18.7; see benches/results.)
#[inline(always)]
fn descend_any<S: Stack>(bvh: &WideBvh<8>, stack: &mut S, child: &[u32; 8], mask: u32) -> Option<u32> {
    if mask & (mask.wrapping_sub(1)) == 0 {
        return (mask != 0).then(|| child[mask.trailing_zeros() as usize]);
    }
    let leaves = mask & leaf_slots(child);
    // Pushed inner nodes first, then leaves, so that leaves pop first.
    for m in [mask & !leaves, leaves] {
        let mut m = m;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            prefetch_ref(bvh, child[i]);
            stack.push(child[i], 0.0);
        }
    }
    stack.pop().map(|(r, _)| r)
}

/// Starts loading the node or leaf block `r` refers to (see [`crate::simd::prefetch`]). Single
/// rays do it for the children they push on the stack (not for a lone child, visited at once);
/// packets for every child they will visit. Their cache misses then overlap other work.
/// Measured on 2 threads: 1M-triangle scene bounce rays 4.9 → 5.7 Mrays/s, its 8-wide primary
/// packets 21.1 → 23.4; Igea bounce 9.2 → 9.7.
#[inline(always)]
pub(crate) fn prefetch_ref(bvh: &WideBvh<8>, r: u32) {
    if r & LEAF_BIT == 0 {
        crate::simd::prefetch(&bvh.nodes[r as usize], 4);
    } else {
        crate::simd::prefetch(&bvh.blocks[leaf_parts(r).0], 4);
    }
}

/// Closest hit in the canonical frame: (t, scene triangle, b1, b2). Small trees use a 16-entry
/// array stack, others a [`SpillStack`]: the array is zeroed for every ray, and zeroing 1 KiB was
/// ~10 % of a Cornell-box shadow ray.
#[inline]
pub(crate) fn closest(bvh: &WideBvh<8>, ray: &CanonicalRay) -> Option<(f32, u32, f32, f32)> {
    if bvh.stack_need() <= 16 {
        closest_with(bvh, ray, &mut ArrayStack::<16>::new())
    } else {
        closest_with(bvh, ray, &mut SpillStack::<(u32, f32), SPILL_AT>::new((0, 0.0)))
    }
}

#[inline(always)]
fn closest_with<S: Stack>(bvh: &WideBvh<8>, ray: &CanonicalRay, stack: &mut S) -> Option<(f32, u32, f32, f32)> {
    let sheared = ShearedRay::new(ray.origin, ray.dir);
    let box_ray = BoxRay::new(ray.origin, ray.dir);
    let mut best_t = ray.t_max;
    let mut best = (EMPTY, 0.0f32, 0.0f32);
    let mut cur = Some(bvh.root);
    loop {
        while let Some(r) = cur {
            if r & LEAF_BIT == 0 {
                let node = &bvh.nodes[r as usize];
                let (t_near, mask) = box_ray.test(&node.bounds, cull_distance(best_t));
                cur = descend(bvh, stack, &node.child, t_near, mask);
            } else {
                let (b, count) = leaf_parts(r);
                let block = &bvh.blocks[b];
                let h = intersect_block(&sheared, block, count, best_t);
                let mut m = h.mask.bitmask();
                if m != 0 {
                    let (t, b1, b2) = (h.t.to_array(), h.b1.to_array(), h.b2.to_array());
                    while m != 0 {
                        let i = m.trailing_zeros() as usize;
                        m &= m - 1;
                        let id = block.id[i];
                        if t[i] < best_t || (t[i] == best_t && id < best.0) {
                            best_t = t[i];
                            best = (id, b1[i], b2[i]);
                        }
                    }
                }
                cur = None;
            }
        }
        // Pop the next entry the closest hit has not passed.
        loop {
            match stack.pop() {
                None => return (best.0 != EMPTY).then_some((best_t, best.0, best.1, best.2)),
                Some((r, t)) if t <= cull_distance(best_t) => {
                    cur = Some(r);
                    break;
                }
                Some(_) => {}
            }
        }
    }
}

/// "No occluder remembered" for [`Accel::occluded_cached`].
pub const NO_OCCLUDER: u32 = u32::MAX;

/// Any hit in (0, t_max) in the canonical frame; the leaf in `hint` (a leaf reference, or
/// [`NO_OCCLUDER`]) is tested first, and the occluding leaf found by a traversal is stored there.
#[inline]
pub(crate) fn occluded(bvh: &WideBvh<8>, ray: &CanonicalRay, hint: &mut u32) -> bool {
    occluded_from_parts(bvh, ShearedRay::new(ray.origin, ray.dir), ray.origin, ray.t_max, hint, || {
        [1.0 / ray.dir.x, 1.0 / ray.dir.y, 1.0 / ray.dir.z]
    })
}

/// [`occluded`] for a ray given by its sheared form and (computed only when the hinted leaf
/// does not block it) its reciprocal direction — one lane of a packet set up all at once.
#[inline(always)]
pub(crate) fn occluded_from_parts(
    bvh: &WideBvh<8>,
    sheared: ShearedRay,
    origin: Vec3,
    t_max: f32,
    hint: &mut u32,
    rdir: impl FnOnce() -> [f32; 3],
) -> bool {
    if *hint != NO_OCCLUDER && leaf_blocks(bvh, &sheared, *hint, t_max) {
        return true;
    }
    let boxes = BoxRay::from_rdir(origin, rdir());
    let leaf = if bvh.stack_need() <= 16 {
        occluder_with(bvh, &sheared, &boxes, t_max, &mut ArrayStack::<16>::new())
    } else {
        occluder_with(bvh, &sheared, &boxes, t_max, &mut SpillStack::<(u32, f32), SPILL_AT>::new((0, 0.0)))
    };
    match leaf {
        Some(r) => {
            *hint = r;
            true
        }
        None => false,
    }
}

/// True when a triangle of leaf `r` blocks the ray in (0, t_max).
#[inline(always)]
fn leaf_blocks(bvh: &WideBvh<8>, sheared: &ShearedRay, r: u32, t_max: f32) -> bool {
    let (b, count) = leaf_parts(r);
    let h = intersect_block(sheared, &bvh.blocks[b], count, t_max);
    h.mask.and(h.t.lt(F4::splat(t_max))).bitmask() != 0
}

/// A leaf that blocks the ray in (0, t_max), if any.
#[inline(always)]
fn occluder_with<S: Stack>(
    bvh: &WideBvh<8>,
    sheared: &ShearedRay,
    boxes: &BoxRay,
    t_max: f32,
    stack: &mut S,
) -> Option<u32> {
    let t_cull = cull_distance(t_max);
    let mut cur = Some(bvh.root);
    loop {
        while let Some(r) = cur {
            if r & LEAF_BIT == 0 {
                let node = &bvh.nodes[r as usize];
                let (_, mask) = boxes.test(&node.bounds, t_cull);
                cur = descend_any(bvh, stack, &node.child, mask);
            } else {
                if leaf_blocks(bvh, sheared, r, t_max) {
                    return Some(r);
                }
                cur = None;
            }
        }
        match stack.pop() {
            None => return None,
            Some((r, _)) => cur = Some(r),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// A spill stack behaves as a plain array stack (push, pop, sorting the top entries)
        /// whether its entries are in the array, in the spill, or straddle the two.
        #[test]
        fn spill_stack_is_a_stack(ops in proptest::collection::vec((0u8..3, 1usize..9, 0u32..1000), 1..200)) {
            let mut spill = SpillStack::<(u32, f32), 4>::new((0, 0.0));
            // The reference: a plain array stack with room for every push.
            let mut plain = ArrayStack::<2048>::new();
            for (op, n, x) in ops {
                match op {
                    0 => {
                        for k in 0..n as u32 {
                            Stack::push(&mut spill, x + k, ((x * 7 + k * 13) % 97) as f32);
                            Stack::push(&mut plain, x + k, ((x * 7 + k * 13) % 97) as f32);
                        }
                    }
                    1 => prop_assert_eq!(Stack::pop(&mut spill), Stack::pop(&mut plain)),
                    _ => {
                        let n = n.min(plain.len);
                        if n > 0 {
                            spill.sort_top(n);
                            plain.sort_top(n);
                        }
                    }
                }
            }
            while let Some(top) = Stack::pop(&mut plain) {
                prop_assert_eq!(Stack::pop(&mut spill), Some(top));
            }
            prop_assert_eq!(Stack::pop(&mut spill), None);
        }
    }
}
