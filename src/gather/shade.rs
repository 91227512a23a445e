//! The gather proper: every pixel sums the contributions `L·f·G·V` of its VPL subset, with G
//! clamped at the bound of `--clamp` (0: no clamp, unbiased). Clamping is reported honestly:
//! the luminance the clamp removed is summed alongside what was kept.

use std::time::{Duration, Instant};

use glam::Vec3;
use rayon::prelude::*;

use super::Tracing;
use super::gbuffer::GBuffer;
use super::interleave::Interleave;
use crate::accel::Accel;
use crate::accel::ray_offset;
use crate::accel::single::NO_OCCLUDER;
use crate::bsdf::BsdfKind;
use crate::color::luminance;
use crate::sampling::IndependentSampler;
use crate::scene::Scene;
use crate::simd::{F4, F8, LaneRay, Lanes, RayPacket};
use crate::stats::RayStats;
use crate::vpl::set::VplLobe;
use crate::vpl::transfer::{Receiver, SHADOW_T_MAX, shadow_segment, unshadowed};
use crate::vpl::{TWO_SIDED, VplSet};
use std::f32::consts::{FRAC_1_PI, PI};

use super::compensate::ResidualRay;
use crate::bsdf::frame::Frame;
use crate::sampling::Sampler;
use crate::sampling::warp::sample_cosine_hemisphere;

/// Energy bookkeeping of one gather.
#[derive(Clone, Copy, Debug, Default)]
pub struct GatherEnergy {
    /// Sum of the luminance of kept (clamped) contributions.
    pub kept: f64,
    /// Sum of the luminance the clamp removed.
    pub removed: f64,
    /// Sum of the luminance the clamp compensation added back (an estimate of `removed` and
    /// of what the clamp removes along the compensation paths; see [`super::compensate`]).
    pub recovered: f64,
}

impl GatherEnergy {
    /// Share of the unclamped energy removed by clamping.
    pub fn removed_share(&self) -> f64 {
        let total = self.kept + self.removed;
        if total > 0.0 { self.removed / total } else { 0.0 }
    }
}

impl std::ops::AddAssign for GatherEnergy {
    fn add_assign(&mut self, o: Self) {
        self.kept += o.kept;
        self.removed += o.removed;
        self.recovered += o.recovered;
    }
}

/// How evenly one gather's VPLs lit the image: the largest luminance a VPL brought to the image
/// (`power[i]`: its contributions summed over the pixels it lit, each at its interleave weight)
/// over the median of those that brought any; None when none did. A VPL far above the median
/// shows as a bright copy of the interleave tile (the 8×8-square symptom) that the
/// discontinuity buffer, which averages one tile, cannot blend away.
pub fn power_ratio(power: &[f32]) -> Option<f32> {
    let mut lit: Vec<f32> = power.iter().copied().filter(|p| *p > 0.0).collect();
    if lit.is_empty() {
        return None;
    }
    let mid = lit.len() / 2;
    let (_, median, above) = lit.select_nth_unstable_by(mid, f32::total_cmp);
    let max = above.iter().copied().fold(*median, f32::max);
    Some(max / *median)
}

/// What [`Gatherer::row`] did.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct RowGathered {
    /// Rays traced.
    pub stats: RayStats,
    /// Energy kept, removed and recovered.
    pub energy: GatherEnergy,
    /// Thread time spent on the clamp compensation.
    pub compensation_time: Duration,
}

/// A shadow ray still to trace: pixel x of the row, its VPL, clamped and unclamped
/// contributions, segment.
type Pending = (u32, u32, Vec3, Vec3, Vec3, Vec3);

/// Per-row accumulation of contributions that pass their shadow rays.
struct RowSums<'s> {
    sum: Vec<Vec3>,
    removed: Vec<Vec3>,
    pending: Vec<Pending>,
    /// Each pixel's interleave scale (the weight of its subset's VPLs there).
    scale: Vec<f32>,
    /// Per VPL, the luminance it brought to the image (see [`VplPower`]); empty: not kept.
    power: &'s mut [f32],
}

impl RowSums<'_> {
    /// Adds VPL i's clamped contribution `c` (and the share `full − c` the clamp removed) to
    /// pixel x.
    #[inline(always)]
    fn add_light(&mut self, x: u32, i: u32, c: Vec3, full: Vec3) {
        self.sum[x as usize] += c;
        self.removed[x as usize] += full - c;
        if let Some(p) = self.power.get_mut(i as usize) {
            *p += luminance(c) * self.scale[x as usize];
        }
    }

    fn add(&mut self, (x, i, c, full, _, _): Pending) {
        self.add_light(x, i, c, full);
    }

    /// Traces the pending shadow rays as one packet (a lone ray as a single ray).
    fn flush(&mut self, accel: &Accel, st: &mut RayStats) {
        st.shadow += self.pending.len() as u64;
        let mut pending = std::mem::take(&mut self.pending);
        if let [(_, _, _, _, o, d)] = pending[..] {
            if !accel.occluded(o, d, SHADOW_T_MAX) {
                self.add(pending[0]);
            }
        } else if !pending.is_empty() {
            let packet = RayPacket::<F8>::from_fn(|j| pending.get(j).map(|p| LaneRay::new(p.4, p.5, SHADOW_T_MAX)));
            let blocked = accel.occluded_packet(&packet);
            for (j, p) in pending.iter().enumerate() {
                if blocked >> j & 1 == 0 {
                    self.add(*p);
                }
            }
        }
        pending.clear();
        self.pending = pending;
    }

    /// Queues a shadow ray, tracing the queue when it holds a full packet.
    fn push(&mut self, p: Pending, accel: &Accel, st: &mut RayStats) {
        self.pending.push(p);
        if self.pending.len() == F8::LANES {
            self.flush(accel, st);
        }
    }
}

/// Shadow rays waiting to be traced, each with its shadow-cache slot (its VPL) and a payload:
/// set up on eight lanes at once ([`Accel::occluded_lanes_cached`]) and traced one by one,
/// whichever receivers they come from (a pixel's subset of four VPLs would leave half of the
/// set-up lanes idle; MIR's probes each send one ray to the same VPL).
pub(crate) struct ShadowBatch<T: Copy + Default> {
    rays: [LaneRay; 8],
    slot: [u32; 8],
    item: [T; 8],
    len: usize,
}

impl<T: Copy + Default> ShadowBatch<T> {
    pub(crate) fn new() -> Self {
        let idle = LaneRay::new(Vec3::ZERO, Vec3::X, 0.0);
        ShadowBatch { rays: [idle; 8], slot: [0; 8], item: [T::default(); 8], len: 0 }
    }

    /// Queues the segment from `o` to `target` (tested up to [`SHADOW_T_MAX`]) with cache slot
    /// `slot`, tracing the batch (see [`ShadowBatch::trace`]) when it is full.
    #[inline(always)]
    pub(crate) fn push(
        &mut self,
        o: Vec3,
        target: Vec3,
        slot: u32,
        item: T,
        accel: &Accel,
        cache: &mut [u32],
        st: &mut RayStats,
        visible: impl FnMut(u32, T),
    ) {
        let k = self.len;
        (self.rays[k], self.slot[k], self.item[k]) = (LaneRay::new(o, target - o, SHADOW_T_MAX), slot, item);
        self.len += 1;
        if self.len == F8::LANES {
            self.trace(accel, cache, st, visible);
        }
    }

    /// Traces the queued rays and calls `visible` with the cache slot and payload of each
    /// unblocked ray, in queue order. Ray k starts from the shadow cache `cache[slot k]` as it was when the batch
    /// was traced (rays of one batch do not see each other's occluders); a blocked ray then
    /// leaves its occluder there, in queue order. The answers do not depend on the cache.
    pub(crate) fn trace(
        &mut self,
        accel: &Accel,
        cache: &mut [u32],
        st: &mut RayStats,
        mut visible: impl FnMut(u32, T),
    ) {
        let n = self.len;
        if n == 0 {
            return;
        }
        let mut hints = [NO_OCCLUDER; 8];
        for k in 0..n {
            hints[k] = cache[self.slot[k] as usize];
        }
        let ray = |k: usize| (k < n).then(|| self.rays[k]);
        let blocked = if n <= 4 {
            accel.occluded_lanes_cached(&RayPacket::<F4>::from_fn(ray), &mut hints)
        } else {
            accel.occluded_lanes_cached(&RayPacket::<F8>::from_fn(ray), &mut hints)
        };
        st.shadow += n as u64;
        for k in 0..n {
            if blocked >> k & 1 != 0 {
                cache[self.slot[k] as usize] = hints[k];
            } else {
                visible(self.slot[k], self.item[k]);
            }
        }
        self.len = 0;
    }
}

/// A G-buffer receiver prepared for the gather's inner loop: the parts of
/// [`unshadowed`] and [`shadow_segment`] that depend on the receiver alone, computed once per
/// pixel instead of once per VPL–pixel pair.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Prepared {
    p: Vec3,
    /// Front geometric normal and the origin offset along it ([`crate::accel::ray_offset`]).
    ng: Vec3,
    offset: f32,
    /// Set for a Lambertian receiver (the common case): the diffuse fast path.
    lambert: Option<LambertReceiver>,
}

/// The factors of a Lambertian receiver's `β · f(wo, wi) · |cos θ_i|` that do not depend on wi.
#[derive(Clone, Copy, Debug)]
struct LambertReceiver {
    /// The BSDF's geometric normal (oriented towards wo) and `wo · ng_o`.
    ng_o: Vec3,
    wo_ng: f32,
    /// The shading normal and `wo · n_s`.
    ns: Vec3,
    wo_ns: f32,
    /// ρ/π.
    f: Vec3,
    beta: Vec3,
}

impl Prepared {
    /// Prepares receiver `r` of `scene`. Always inlined: called out of line from the G-buffer's
    /// loop, its result came back through memory and the copy into the band's slot stalled
    /// (benches/results/2026-12-01-view.md, fourth session).
    #[inline(always)]
    pub(crate) fn new(scene: &Scene, r: &Receiver) -> Self {
        let lambert = match r.bsdf.kind {
            BsdfKind::Lambert { albedo } => Some(LambertReceiver {
                ng_o: r.bsdf.ng,
                wo_ng: r.wo.dot(r.bsdf.ng),
                ns: r.bsdf.frame.n,
                wo_ns: r.wo.dot(r.bsdf.frame.n),
                f: albedo * FRAC_1_PI,
                beta: r.beta,
            }),
            _ => None,
        };
        let offset = ray_offset(r.sp.p, &scene.mesh.corners(r.sp.tri));
        Prepared { p: r.sp.p, ng: r.sp.ng, offset, lambert }
    }

    /// The clamped contribution of VPL `i` before visibility, and the shadow segment (origin,
    /// target) that decides it; None when the contribution is zero.
    #[inline]
    pub(crate) fn unshadowed(&self, r: &Receiver, set: &VplSet, i: usize, g_max: f32) -> Option<(Vec3, Vec3, Vec3)> {
        let c = match &self.lambert {
            Some(l) if set.lobe[i] == crate::vpl::set::NO_LOBE => l.unshadowed(set, i, self.p, g_max),
            _ => unshadowed(set, i, r, g_max),
        };
        let (c, _) = c?;
        let target = set.position[i];
        Some((c, self.origin_towards(target), target))
    }

    /// The clamp compensation's ray of a Lambertian receiver: [`Compensation::sample_ray`]
    /// without the general BSDF (a cosine-distributed direction about the shading normal on
    /// the viewer's side, kept when it leaves on the viewer's geometric side too; weight ρ·β).
    /// Same two samples consumed, same distribution. None for other BSDFs.
    #[inline]
    fn compensation_ray(&self, sampler: &mut impl Sampler) -> Option<Option<ResidualRay>> {
        let l = self.lambert.as_ref()?;
        let (_, u) = (sampler.next_1d(), sampler.next_2d());
        if l.wo_ns == 0.0 {
            return Some(None);
        }
        let local = sample_cosine_hemisphere(u);
        let n = if l.wo_ns > 0.0 { l.ns } else { -l.ns };
        let wi = Frame::from_normal(n).to_world(local);
        if !(local.z > 0.0) || !(l.wo_ng * wi.dot(l.ng_o) > 0.0) {
            return Some(None);
        }
        let weight = l.beta * l.f * PI;
        Some(Some(ResidualRay { origin: self.origin_towards(self.p + wi), dir: wi, cos_x: local.z, weight }))
    }

    /// The shadow-ray origin towards `target`, as [`shadow_segment`] places it.
    #[inline(always)]
    pub(crate) fn origin_towards(&self, target: Vec3) -> Vec3 {
        if self.ng.dot(target - self.p) >= 0.0 {
            self.p + self.ng * self.offset
        } else {
            self.p - self.ng * self.offset
        }
    }
}

impl LambertReceiver {
    /// [`unshadowed`] for a diffuse VPL `i` and this receiver at `p`: the same operations in the
    /// same order, so the same bits (`tests/packet_vs_scalar.rs` compares whole images).
    #[inline(always)]
    fn unshadowed(&self, set: &VplSet, i: usize, p: Vec3, g_max: f32) -> Option<(Vec3, Vec3)> {
        let d = set.position[i] - p;
        let d2 = d.length_squared();
        if !(d2 > 0.0) {
            return None;
        }
        let wi = d / d2.sqrt();
        let cos_v = set.cos_at(i, -wi);
        if cos_v <= 0.0 {
            return None;
        }
        // Bsdf::f: reflection on the geometric normal, then Lambert's same-side test.
        if !(self.wo_ng * wi.dot(self.ng_o) > 0.0) {
            return None;
        }
        let wi_ns = wi.dot(self.ns);
        if self.wo_ns * wi_ns <= 0.0 || self.f == Vec3::ZERO {
            return None;
        }
        if set.radiance[i] == Vec3::ZERO {
            return None;
        }
        let g = cos_v * wi_ns.abs() / d2;
        let base = self.beta * set.radiance[i] * self.f;
        Some((base * g.min(g_max), base * g))
    }
}

/// Eight VPLs of one interleave subset in lanes, for [`LambertReceiver::unshadowed8`]: diffuse
/// VPLs, and Lambertian surface VPLs whose shading normal differs from their geometric normal
/// (smooth-shaded meshes), whose radiance towards w is `r·f(wo, w)·(shading correction)`.
#[derive(Clone, Copy)]
struct VplChunk {
    /// VPL index of each lane.
    index: [u32; 8],
    /// Lanes holding a VPL (low bits).
    lanes: u32,
    position: [F8; 3],
    normal: [F8; 3],
    /// Diffuse lanes: the radiance; smooth lanes: `r · ρ/π` (the lobe's factor times its BSDF
    /// value on the reflecting side).
    radiance: [F8; 3],
    /// Masks: the VPL is punctual (zero normal, cosine 1); it emits on both sides.
    punctual: F8,
    two_sided: F8,
    /// Smooth lanes: the mask, the lobe's shading normal and geometric normal, and `wo·n_s`,
    /// `wo·n_g` for its `wo` (zero in diffuse lanes).
    smooth: F8,
    smooth_lanes: u32,
    lobe_ns: [F8; 3],
    lobe_ng: [F8; 3],
    wo_ns: F8,
    wo_ng: F8,
}

/// The albedo, BSDF and `wo` of VPL `i`'s lobe when it is a Lambertian surface (None: a diffuse
/// VPL, or another lobe).
fn lambert_lobe(vpls: &VplSet, i: usize) -> Option<(Vec3, &crate::bsdf::Bsdf, Vec3)> {
    match vpls.lobe[i] {
        crate::vpl::set::NO_LOBE => None,
        l => match &vpls.lobes[l as usize] {
            VplLobe::Surface { bsdf, wo } => match bsdf.kind {
                BsdfKind::Lambert { albedo } => Some((albedo, bsdf, *wo)),
                _ => None,
            },
            VplLobe::Spot { .. } => None,
        },
    }
}

/// True when every VPL fits the 8-VPL kernel: diffuse, or a Lambertian surface lobe.
fn chunkable(vpls: &VplSet) -> bool {
    vpls.all_diffuse()
        || (0..vpls.len()).all(|i| vpls.lobe[i] == crate::vpl::set::NO_LOBE || lambert_lobe(vpls, i).is_some())
}

/// The VPLs of every interleave subset, eight to a chunk, in subset order.
fn chunk_subsets(vpls: &VplSet, inter: &Interleave) -> Vec<Vec<VplChunk>> {
    inter.subsets.iter().map(|subset| subset.chunks(F8::LANES).map(|ids| VplChunk::new(vpls, ids)).collect()).collect()
}

impl VplChunk {
    /// The VPLs `ids` (at most eight, each diffuse or with a Lambertian lobe) of `vpls` in lanes.
    fn new(vpls: &VplSet, ids: &[u32]) -> Self {
        debug_assert!(ids.len() <= F8::LANES);
        let at = |f: &dyn Fn(usize) -> f32| F8::from_fn(|j| ids.get(j).map_or(0.0, |&i| f(i as usize)));
        let bits =
            |f: &dyn Fn(usize) -> bool| ids.iter().enumerate().fold(0, |m, (j, &i)| m | (f(i as usize) as u32) << j);
        let flag = |f: &dyn Fn(usize) -> bool| F8::mask_from_bits(bits(f));
        let lobe = |i: usize| lambert_lobe(vpls, i);
        let smooth_lanes = bits(&|i| lobe(i).is_some());
        // What `VplSet::radiance` multiplies by the shading correction: r · (ρ/π).
        let factor = |i: usize| match lobe(i) {
            Some((albedo, _, _)) => vpls.radiance[i] * (albedo * FRAC_1_PI),
            None => vpls.radiance[i],
        };
        let lobe_at = |f: &dyn Fn(&crate::bsdf::Bsdf, Vec3) -> f32| at(&|i| lobe(i).map_or(0.0, |(_, b, wo)| f(b, wo)));
        VplChunk {
            index: std::array::from_fn(|j| ids.get(j).copied().unwrap_or(0)),
            lanes: (1u32 << ids.len()) - 1,
            position: [at(&|i| vpls.position[i].x), at(&|i| vpls.position[i].y), at(&|i| vpls.position[i].z)],
            normal: [at(&|i| vpls.normal[i].x), at(&|i| vpls.normal[i].y), at(&|i| vpls.normal[i].z)],
            radiance: [at(&|i| factor(i).x), at(&|i| factor(i).y), at(&|i| factor(i).z)],
            punctual: flag(&|i| vpls.normal[i] == Vec3::ZERO),
            two_sided: flag(&|i| vpls.flags[i] & TWO_SIDED != 0),
            smooth: F8::mask_from_bits(smooth_lanes),
            smooth_lanes,
            lobe_ns: [lobe_at(&|b, _| b.frame.n.x), lobe_at(&|b, _| b.frame.n.y), lobe_at(&|b, _| b.frame.n.z)],
            lobe_ng: [lobe_at(&|b, _| b.ng.x), lobe_at(&|b, _| b.ng.y), lobe_at(&|b, _| b.ng.z)],
            wo_ns: lobe_at(&|b, wo| wo.dot(b.frame.n)),
            wo_ng: lobe_at(&|b, wo| wo.dot(b.ng)),
        }
    }
}

/// Up to eight VPLs of a set evaluated together at one receiver: MIR's probe normalisation
/// measures eight VPLs per pass over its probes with the gather's eight-lane kernel (the
/// general kernels for receivers or VPLs outside it), with the same bits as
/// [`Prepared::unshadowed`] per VPL.
pub(crate) struct VplLanes {
    /// The eight-lane form, when every VPL fits it.
    chunk: Option<VplChunk>,
    len: usize,
}

impl VplLanes {
    /// The whole of `set` (at most eight VPLs) in lanes; lane j is VPL j.
    pub(crate) fn new(set: &VplSet) -> Self {
        assert!(set.len() <= F8::LANES, "at most eight VPLs in lanes");
        let ids: Vec<u32> = (0..set.len() as u32).collect();
        VplLanes { chunk: chunkable(set).then(|| VplChunk::new(set, &ids)), len: set.len() }
    }

    /// Calls `f(j, contribution)` for every lane j of `active` whose VPL has a nonzero
    /// unshadowed contribution at `r` (clamped at `g_max`), in lane order. (Its shadow ray
    /// starts at [`Prepared::origin_towards`] the VPL.)
    #[inline]
    pub(crate) fn each_unshadowed(
        &self,
        set: &VplSet,
        pt: &Prepared,
        r: &Receiver,
        active: u32,
        g_max: f32,
        mut f: impl FnMut(usize, Vec3),
    ) {
        let active = active & ((1u32 << self.len) - 1);
        if let (Some(ch), Some(l)) = (&self.chunk, &pt.lambert) {
            let lc = l.unshadowed8(ch, pt.p, g_max, 0.0);
            let mut m = lc.lanes & active;
            while m != 0 {
                let j = m.trailing_zeros() as usize;
                m &= m - 1;
                f(j, lc.lane(j).0);
            }
        } else {
            let mut m = active;
            while m != 0 {
                let j = m.trailing_zeros() as usize;
                m &= m - 1;
                if let Some((c, _, _)) = pt.unshadowed(r, set, j, g_max) {
                    f(j, c);
                }
            }
        }
    }
}

/// Clamped and unclamped contributions of up to eight VPLs, and the lanes where they are nonzero.
struct LaneContributions {
    lanes: u32,
    /// Per lane: the clamped contribution's r, g, b, then the unclamped one's (transposed from
    /// the kernel's channel vectors, so a lane is read from one store: read across the channel
    /// arrays, its values were merged into one wide load spanning two stores still in flight,
    /// which stalled the gather).
    by_lane: [[f32; 8]; 8],
}

impl LaneContributions {
    /// The clamped and unclamped contribution of lane `j`.
    #[inline(always)]
    fn lane(&self, j: usize) -> (Vec3, Vec3) {
        let v = &self.by_lane[j];
        (Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]))
    }
}

impl LambertReceiver {
    /// [`LambertReceiver::unshadowed`] for the eight VPLs of `ch` at once, lane for lane the
    /// same operations (no fused multiply-adds), so the same bits; lanes closer than
    /// `min_d2` (squared) are dropped as the scalar gather drops them.
    #[inline(always)]
    fn unshadowed8(&self, ch: &VplChunk, p: Vec3, g_max: f32, min_d2: f32) -> LaneContributions {
        let (zero, one) = (F8::splat(0.0), F8::splat(1.0));
        let d = [ch.position[0] - F8::splat(p.x), ch.position[1] - F8::splat(p.y), ch.position[2] - F8::splat(p.z)];
        let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        // (A black receiver reflects nothing: no lanes.)
        let lanes = if self.f == Vec3::ZERO { 0 } else { ch.lanes };
        let mut valid = F8::mask_from_bits(lanes).and(d2.gt(zero));
        if min_d2 > 0.0 {
            valid = valid.and_not(d2.lt(F8::splat(min_d2)));
        }
        let dist = d2.sqrt();
        let wi = [d[0] / dist, d[1] / dist, d[2] / dist];
        let dot = |a: &[F8; 3], v: Vec3| a[0] * F8::splat(v.x) + a[1] * F8::splat(v.y) + a[2] * F8::splat(v.z);
        let dot3 = |a: &[F8; 3], b: &[F8; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        // cos_at(−wi): the VPL normal against the direction back to it.
        let c = zero - (ch.normal[0] * wi[0] + ch.normal[1] * wi[1] + ch.normal[2] * wi[2]);
        let cos_v = ch.punctual.select(one, ch.two_sided.select(c.abs(), c.vmax(zero)));
        valid = valid.and_not(cos_v.le(zero));
        valid = valid.and((F8::splat(self.wo_ng) * dot(&wi, self.ng_o)).gt(zero));
        let wi_ns = dot(&wi, self.ns);
        valid = valid.and_not((F8::splat(self.wo_ns) * wi_ns).le(zero));
        let g = cos_v * wi_ns.abs() / d2;
        let g_c = g.vmin(F8::splat(g_max));
        // Smooth lanes: the lobe's radiance towards w = −wi, as `VplSet::radiance` evaluates it
        // (Bsdf::f's reflection and Lambert side tests, then the shading correction). Lanes
        // where it is zero are dropped: their contribution is zero.
        let mut le = ch.radiance;
        if ch.smooth_lanes & lanes != 0 {
            let w_ng = zero - dot3(&wi, &ch.lobe_ng);
            let w_ns = zero - dot3(&wi, &ch.lobe_ns);
            let lit = (ch.wo_ng * w_ng).gt(zero).and_not((ch.wo_ns * w_ns).le(zero));
            let num = ch.wo_ns.abs() * w_ng.abs();
            let den = ch.wo_ng.abs() * w_ns.abs();
            let sc = den.eq(zero).select(zero, num / den);
            for (l, r) in le.iter_mut().zip(&ch.radiance) {
                *l = ch.smooth.select(lit.select(*r * sc, zero), *r);
            }
        }
        // No radiance towards the receiver: no contribution and no shadow ray (as the scalar
        // kernels).
        valid = valid.and_not(le[0].eq(zero).and(le[1].eq(zero)).and(le[2].eq(zero)));
        let base = |k: usize| F8::splat(self.beta[k]) * le[k] * F8::splat(self.f[k]);
        let (b0, b1, b2) = (base(0), base(1), base(2));
        let by_lane = F8::transpose([b0 * g_c, b1 * g_c, b2 * g_c, b0 * g, b1 * g, b2 * g, zero, zero]);
        LaneContributions { lanes: valid.bitmask(), by_lane: by_lane.map(|v| v.to_array()) }
    }
}

/// Stream tag of the clamp compensation's paths.
const TAG_COMPENSATE: u64 = 0x434f_4d50_454e;

/// What every row of a gather shares: the scene, the VPLs and their subsets, the clamp.
pub(crate) struct Gatherer<'a> {
    scene: &'a Scene,
    accel: &'a Accel,
    vpls: &'a VplSet,
    inter: &'a Interleave,
    g_max: f32,
    min_d2: f32,
    tracing: Tracing,
    diffuse_vpls: bool,
    /// The subsets' VPLs in lanes, for the Lambertian fast path (diffuse or Lambertian-lobe VPLs,
    /// single shadow rays).
    chunks: Option<Vec<Vec<VplChunk>>>,
    /// Seed of the clamp compensation's paths, when it is on ([`super::compensate`]).
    compensate: Option<u64>,
    /// One pixel in this many is compensated, at this weight (≥ 1).
    stride: u32,
}

impl<'a> Gatherer<'a> {
    pub(crate) fn new(
        scene: &'a Scene,
        accel: &'a Accel,
        vpls: &'a VplSet,
        inter: &'a Interleave,
        g_max: f32,
        min_distance: f32,
        tracing: Tracing,
    ) -> Self {
        let diffuse_vpls = vpls.all_diffuse();
        let chunks = (matches!(tracing, Tracing::Single | Tracing::PrimaryPackets) && chunkable(vpls))
            .then(|| chunk_subsets(vpls, inter));
        let min_d2 = min_distance * min_distance;
        Gatherer {
            scene,
            accel,
            vpls,
            inter,
            g_max,
            min_d2,
            tracing,
            diffuse_vpls,
            chunks,
            compensate: None,
            stride: 1,
        }
    }

    /// Adds the clamp compensation (a residual path per pixel, seeded by `seed`) when `seed` is
    /// given and the gather clamps; at one pixel in `stride` only, weighted by `stride` (pixel
    /// (x, y) when (x + y + seed) mod stride = 0).
    pub(crate) fn compensating(self, seed: Option<u64>, stride: u32) -> Self {
        Gatherer { compensate: seed.filter(|_| self.g_max.is_finite()), stride: stride.max(1), ..self }
    }

    /// The shadow ray from the prepared receiver `pt` of pixel x to VPL i, with its
    /// contributions (None: nothing to trace — too close, or zero unshadowed contribution).
    #[inline]
    fn candidate(&self, pt: &Prepared, r: &Receiver, x: u32, i: usize) -> Option<Pending> {
        let vpls = self.vpls;
        let target = vpls.position[i];
        if self.min_d2 > 0.0 && (target - pt.p).length_squared() < self.min_d2 {
            return None;
        }
        let (c, full) = match &pt.lambert {
            Some(l) if self.diffuse_vpls => l.unshadowed(vpls, i, pt.p, self.g_max)?,
            _ => unshadowed(vpls, i, r, self.g_max)?,
        };
        let o = pt.origin_towards(target);
        Some((x, i as u32, c, full, o, target - o))
    }

    /// Which prepared receivers [`Gatherer::row`] also needs the receiver of.
    pub(crate) fn keeps_receiver(&self) -> fn(&Prepared) -> bool {
        if self.keeps_all_receivers() { |_| true } else { |pt| pt.lambert.is_none() }
    }

    /// Whether [`Gatherer::row`] needs every receiver (the packet groupings, or VPLs outside the
    /// eight-VPL kernel), not only the non-Lambertian ones.
    pub(crate) fn keeps_all_receivers(&self) -> bool {
        !self.inter.regional.is_empty()
            || !matches!((self.tracing, &self.chunks), (Tracing::Single | Tracing::PrimaryPackets, Some(_)))
    }

    /// Gathers row `y` from its receivers into `out` (VPL-transported light, interleave-scaled).
    /// `prepared`, when given, holds the row's receivers already prepared; `receivers` then
    /// needs only those that [`Gatherer::keeps_receiver`] keeps. With the clamp compensated,
    /// `compensation` (when given) receives each pixel's residual alone (it is in `out` too).
    /// `power`, unless empty, has one slot per VPL and receives the luminance each brought to
    /// the row (compensation excluded; see [`VplPower`]).
    pub(crate) fn row(
        &self,
        y: u32,
        receivers: &[Option<Receiver>],
        prepared: Option<&[Option<Prepared>]>,
        out: &mut [Vec3],
        compensation: Option<&mut [Vec3]>,
        power: &mut [f32],
    ) -> RowGathered {
        let Gatherer { scene, accel, vpls, inter, g_max, min_d2, .. } = *self;
        let w = out.len() as u32;
        let subsets = inter.row(y);
        let mut st = RayStats::default();
        // The packet groupings visit pixels out of order: their receivers are prepared first.
        let row_points: Vec<Option<Prepared>> = match self.tracing {
            Tracing::SharedOrigin | Tracing::SharedEnd => {
                receivers.iter().map(|r| r.as_ref().map(|r| Prepared::new(scene, r))).collect()
            }
            Tracing::Single | Tracing::PrimaryPackets => Vec::new(),
        };
        let candidate = |x: u32, i: usize| {
            let r = receivers[x as usize].as_ref()?;
            self.candidate(row_points[x as usize].as_ref()?, r, x, i)
        };
        let mut acc = RowSums {
            sum: vec![Vec3::ZERO; w as usize],
            removed: vec![Vec3::ZERO; w as usize],
            pending: Vec::with_capacity(F8::LANES),
            scale: if power.is_empty() { Vec::new() } else { (0..w).map(|x| inter.scales[subsets.of(x)]).collect() },
            power,
        };
        match self.tracing {
            Tracing::Single | Tracing::PrimaryPackets => {
                // Shadow cache: per VPL, the leaf that last blocked a ray to it in this row.
                let mut occluders = vec![NO_OCCLUDER; vpls.len()];
                // Pixel, clamped and unclamped contribution of each queued ray.
                let mut batch = ShadowBatch::<(u32, Vec3, Vec3)>::new();
                let add = |acc: &mut RowSums, i: u32, (x, c, full): (u32, Vec3, Vec3)| acc.add_light(x, i, c, full);
                for x in 0..w {
                    // Prepared here, pixel by pixel, unless the G-buffer did it: collected into
                    // a row first, each one was copied through memory (measured in
                    // benches/results/2026-12-01-view.md).
                    let local;
                    let pt = match prepared {
                        Some(p) => match &p[x as usize] {
                            Some(pt) => pt,
                            None => continue,
                        },
                        None => match &receivers[x as usize] {
                            Some(r) => {
                                local = Prepared::new(scene, r);
                                &local
                            }
                            None => continue,
                        },
                    };
                    // Lambertian receiver, diffuse or Lambertian-lobe VPLs: eight VPLs at a time.
                    if let Some(chunks) = &self.chunks
                        && let Some(l) = &pt.lambert
                    {
                        if l.f == Vec3::ZERO {
                            continue;
                        }
                        for ch in &chunks[subsets.of(x)] {
                            let lc = l.unshadowed8(ch, pt.p, g_max, min_d2);
                            if lc.lanes == 0 {
                                continue;
                            }
                            // The chunk's shadow rays join the row's batch: set up eight at a
                            // time, across pixels, and traced one by one.
                            let mut m = lc.lanes;
                            while m != 0 {
                                let j = m.trailing_zeros() as usize;
                                m &= m - 1;
                                let i = ch.index[j];
                                let target = vpls.position[i as usize];
                                let o = pt.origin_towards(target);
                                let (c, full) = lc.lane(j);
                                let add = |i, item| add(&mut acc, i, item);
                                batch.push(o, target, i, (x, c, full), accel, &mut occluders, &mut st, add);
                            }
                        }
                        continue;
                    }
                    // Any other receiver or VPL: the general kernels, the same batched rays.
                    let r = receivers[x as usize].as_ref().expect("a receiver kept for the general kernels");
                    for &i in &inter.subsets[subsets.of(x)] {
                        if let Some((x, _, c, full, o, _)) = self.candidate(pt, r, x, i as usize) {
                            let add = |i, item| add(&mut acc, i, item);
                            let target = vpls.position[i as usize];
                            batch.push(o, target, i, (x, c, full), accel, &mut occluders, &mut st, add);
                        }
                    }
                }
                batch.trace(accel, &mut occluders, &mut st, |i, item| add(&mut acc, i, item));
            }
            Tracing::SharedOrigin => {
                for x in 0..w {
                    for &i in &inter.subsets[inter.subset_of(x, y)] {
                        if let Some(p) = candidate(x, i as usize) {
                            acc.push(p, accel, &mut st);
                        }
                    }
                    acc.flush(accel, &mut st);
                }
            }
            Tracing::SharedEnd => {
                // Pixels x ≡ ox (mod n) of this row gather the same subset: packets of up
                // to 8 of them towards each VPL of it.
                let stride = inter.n as usize * F8::LANES;
                for ox in 0..inter.n.min(w) {
                    let subset = &inter.subsets[inter.subset_of(ox, y)];
                    for start in (ox..w).step_by(stride) {
                        let xs = (start..w).step_by(inter.n as usize).take(F8::LANES);
                        for &i in subset {
                            for x in xs.clone() {
                                if let Some(p) = candidate(x, i as usize) {
                                    acc.pending.push(p);
                                }
                            }
                            acc.flush(accel, &mut st);
                        }
                    }
                }
            }
        }
        let mut energy = GatherEnergy::default();
        for (x, o) in out.iter_mut().enumerate() {
            let s = inter.scales[subsets.of(x as u32)];
            let (sum, removed) = (acc.sum[x], acc.removed[x]);
            energy.kept += (luminance(sum) * s) as f64;
            energy.removed += (luminance(removed) * s) as f64;
            *o = sum * s;
        }
        let power = acc.power;
        // Regional VPLs (see `Interleave::regional`): weight 1 at the pixels of their region,
        // their home subset's scale at that subset's pixels outside it; single rays.
        if !inter.regional.is_empty() {
            // The row's pixel offsets in the tile and the subset each gathers.
            let offsets: Vec<(u32, usize)> = (0..inter.n.min(w)).map(|i| (i, subsets.of(i))).collect();
            for reg in &inter.regional {
                let i = reg.vpl as usize;
                let mut gather = |x: u32, weight: f32| {
                    let Some(r) = receivers[x as usize].as_ref() else { return };
                    if min_d2 > 0.0 && (vpls.position[i] - r.sp.p).length_squared() < min_d2 {
                        return;
                    }
                    let Some((c, full)) = unshadowed(vpls, i, r, g_max) else { return };
                    let (origin, d) = shadow_segment(scene, vpls, i, r);
                    st.shadow += 1;
                    if !accel.occluded(origin, d, SHADOW_T_MAX) {
                        energy.kept += (luminance(c) * weight) as f64;
                        energy.removed += (luminance(full - c) * weight) as f64;
                        out[x as usize] += c * weight;
                        if let Some(p) = power.get_mut(i) {
                            *p += luminance(c) * weight;
                        }
                    }
                };
                let [x0, y0, x1, y1] = reg.rect;
                let row_in = y >= y0 && y <= y1;
                if row_in {
                    for x in x0..=x1.min(w - 1) {
                        gather(x, 1.0);
                    }
                }
                let scale = inter.scales[reg.home as usize];
                for &(ox, _) in offsets.iter().filter(|(_, k)| *k == reg.home as usize) {
                    for x in (ox..w).step_by(inter.n as usize) {
                        if !(row_in && x >= x0 && x <= x1) {
                            gather(x, scale);
                        }
                    }
                }
            }
        }
        let mut compensation_time = Duration::ZERO;
        if let Some(seed) = self.compensate {
            let t = Instant::now();
            let comp = super::compensate::Compensation { scene, accel, g_max, min_d2 };
            let mut aov = compensation;
            // One stream per row, its pixels in order (rows are gathered whole, so the image
            // does not depend on the thread count).
            let mut sampler = IndependentSampler::for_stream(seed, TAG_COMPENSATE, y as u64);
            let stride = self.stride as u64;
            let phase = (y as u64 + seed % stride) % stride;
            for (x, o) in out.iter_mut().enumerate() {
                let c = if !(x as u64 + phase).is_multiple_of(stride) {
                    Vec3::ZERO
                } else {
                    // Lambertian receivers through their prepared form (the G-buffer keeps
                    // only that), the others through their BSDF.
                    let local = match prepared {
                        Some(_) => None,
                        None => receivers[x].as_ref().map(|r| Prepared::new(scene, r)),
                    };
                    let pt = match prepared {
                        Some(p) => p[x].as_ref(),
                        None => local.as_ref(),
                    };
                    let ray = match (pt.and_then(|p| p.compensation_ray(&mut sampler)), &receivers[x]) {
                        (Some(ray), _) => ray.map(|ray| (pt.map_or(Vec3::ZERO, |p| p.p), ray)),
                        (None, Some(r)) => comp.sample_ray(r, &mut sampler).map(|ray| (r.sp.p, ray)),
                        (None, None) => None,
                    };
                    match ray {
                        Some((p, ray)) => comp.trace(p, &ray, &mut sampler, &mut st) * self.stride as f32,
                        None => Vec3::ZERO,
                    }
                };
                energy.recovered += luminance(c) as f64;
                *o += c;
                if let Some(a) = aov.as_deref_mut() {
                    a[x] = c;
                }
            }
            compensation_time = t.elapsed();
        } else if let Some(a) = compensation {
            a.fill(Vec3::ZERO);
        }
        RowGathered { stats: st, energy, compensation_time }
    }
}

/// Gathers `vpls` into an image of VPL-transported light (emission seen directly is not
/// included; see [`GBuffer::emitted`]). `tracing` groups the shadow rays into packets (or not);
/// every grouping traces the same rays and gives the same image.
pub fn gather(
    scene: &Scene,
    accel: &Accel,
    gbuf: &GBuffer,
    vpls: &VplSet,
    inter: &Interleave,
    g_max: f32,
    min_distance: f32,
    tracing: Tracing,
    stats: &mut RayStats,
) -> (Vec<Vec3>, GatherEnergy) {
    let w = gbuf.width as usize;
    assert_eq!(gbuf.receivers.len(), w * gbuf.height as usize, "a G-buffer with receivers");
    let gatherer = Gatherer::new(scene, accel, vpls, inter, g_max, min_distance, tracing);
    let mut out = vec![Vec3::ZERO; gbuf.receivers.len()];
    let rows: Vec<RowGathered> = out
        .par_chunks_mut(w.max(1))
        .zip(gbuf.receivers.par_chunks(w.max(1)))
        .enumerate()
        .map(|(y, (out, receivers))| gatherer.row(y as u32, receivers, None, out, None, &mut []))
        .collect();
    let mut energy = GatherEnergy::default();
    for r in rows {
        *stats += r.stats;
        energy += r.energy;
    }
    (out, energy)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::offset_origin;
    use crate::load::builtin;
    use crate::scene::CameraSettings;
    use crate::vpl::VplSampler;
    use crate::vpl::sir::Sir;

    /// The glass-sphere box with its sphere made a matte, smooth-shaded Lambertian (VPLs on it
    /// carry a lobe with a shading correction).
    fn matte_sphere() -> crate::load::desc::SceneDesc {
        let mut desc = builtin::glass_sphere();
        for m in &mut desc.materials {
            if m.name == "glass" {
                m.scatter = crate::load::desc::ScatterDesc::Diffuse;
                m.base_color = Vec3::new(0.7, 0.6, 0.5);
            }
        }
        desc
    }

    /// `desc`'s scene, its BVH, its camera at w×h and a G-buffer traced with `seed`.
    fn traced(
        desc: crate::load::desc::SceneDesc,
        (w, h): (u32, u32),
        seed: u64,
    ) -> (Scene, Accel, crate::scene::Camera, GBuffer) {
        let scene = Scene::from_desc(desc, &CameraSettings::default()).unwrap();
        let accel = Accel::build(&scene.mesh);
        let mut camera = scene.camera.clone();
        (camera.width, camera.height) = (w, h);
        let mut st = RayStats::default();
        let gbuf = super::super::gbuffer::trace(
            &scene,
            &accel,
            &camera,
            seed,
            true,
            4,
            Tracing::PrimaryPackets,
            GBuffer::default(),
            &mut st,
        );
        (scene, accel, camera, gbuf)
    }

    /// The prepared receivers give the bits of the general kernels: every (receiver, VPL) pair
    /// of a Cornell-box frame (Lambertian receivers, diffuse VPLs on walls and the light).
    #[test]
    fn prepared_receivers_match_the_general_kernels_bit_for_bit() {
        let (scene, accel, camera, gbuf) = traced(builtin::cornell(), (48, 48), 7);
        let (vpls, _) = Sir::new(4).sample(&scene, &accel, &camera, 64, 11);
        assert!(vpls.all_diffuse() && vpls.len() >= 64);
        let mut pairs = 0;
        let chunks = chunk_subsets(&vpls, &Interleave::new(&vpls, 1, 1));
        for r in gbuf.receivers.iter().flatten() {
            let pt = Prepared::new(&scene, r);
            let lambert = pt.lambert.as_ref().expect("the Cornell box is Lambertian");
            // The eight-lane kernel against the scalar one, lane for lane.
            for ch in &chunks[0] {
                for (g_max, min_d2) in [(0.05, 0.0), (f32::INFINITY, 0.0), (f32::INFINITY, 0.5)] {
                    let lc = lambert.unshadowed8(ch, pt.p, g_max, min_d2);
                    for j in 0..ch.lanes.count_ones() as usize {
                        let i = ch.index[j] as usize;
                        let near = (vpls.position[i] - pt.p).length_squared() < min_d2;
                        let scalar = lambert.unshadowed(&vpls, i, pt.p, g_max).filter(|_| !near);
                        assert_eq!(lc.lanes >> j & 1 != 0, scalar.is_some(), "lane {j}, VPL {i}");
                        if let Some((c, full)) = scalar {
                            assert_eq!(lc.lane(j), (c, full), "lane {j}, VPL {i}");
                        }
                    }
                }
            }
            for i in 0..vpls.len() {
                for g_max in [0.05, f32::INFINITY] {
                    let fast = lambert.unshadowed(&vpls, i, pt.p, g_max);
                    let general = unshadowed(&vpls, i, r, g_max);
                    assert_eq!(fast.is_some(), general.is_some(), "receiver {:?}, VPL {i}", r.sp.p);
                    if let (Some(a), Some(b)) = (fast, general) {
                        assert_eq!(a, b);
                        pairs += 1;
                    }
                }
                let target = vpls.position[i];
                let origin = offset_origin(&r.sp, &scene.mesh.corners(r.sp.tri), target - r.sp.p);
                assert_eq!(pt.origin_towards(target), origin);
            }
        }
        assert!(pairs > 10_000, "only {pairs} contributing pairs");
    }

    /// Smooth-shaded Lambertian VPLs (shading normal ≠ geometric normal: a matte icosphere with
    /// vertex normals in the Cornell box) go through the eight-lane kernel with the bits of the
    /// general kernel (`VplSet::radiance` with Bsdf::f and the shading correction): a lane is
    /// set exactly when the general kernel gives a contribution, and then it is the same.
    #[test]
    fn smooth_lambert_vpls_match_the_general_kernel_bit_for_bit() {
        let (scene, accel, camera, gbuf) = traced(matte_sphere(), (32, 32), 3);
        let (vpls, _) = Sir::new(4).sample(&scene, &accel, &camera, 2048, 5);
        let smooth = (0..vpls.len()).filter(|&i| lambert_lobe(&vpls, i).is_some()).count();
        assert!(smooth >= 20 && chunkable(&vpls) && !vpls.all_diffuse(), "{smooth} smooth VPLs");
        let chunks = chunk_subsets(&vpls, &Interleave::new(&vpls, 1, 1));
        let (mut pairs, mut smooth_pairs, mut dark) = (0, 0, 0);
        for r in gbuf.receivers.iter().flatten() {
            let pt = Prepared::new(&scene, r);
            let Some(lambert) = pt.lambert.as_ref() else { continue };
            for ch in &chunks[0] {
                for (g_max, min_d2) in [(0.05, 0.0), (f32::INFINITY, 0.0), (f32::INFINITY, 0.5)] {
                    let lc = lambert.unshadowed8(ch, pt.p, g_max, min_d2);
                    for j in 0..ch.lanes.count_ones() as usize {
                        let i = ch.index[j] as usize;
                        let near = (vpls.position[i] - pt.p).length_squared() < min_d2;
                        let general = unshadowed(&vpls, i, r, g_max).filter(|_| !near);
                        assert_eq!(lc.lanes >> j & 1 != 0, general.is_some(), "lane {j}, VPL {i}");
                        if let Some((c, full)) = general {
                            assert_eq!(lc.lane(j), (c, full), "lane {j}, VPL {i}");
                            pairs += 1;
                            smooth_pairs += (ch.smooth_lanes >> j & 1) as usize;
                        } else if ch.smooth_lanes >> j & 1 != 0 && !near {
                            dark += 1;
                        }
                    }
                }
            }
        }
        assert!(smooth_pairs > 1_000 && pairs > 10_000, "{smooth_pairs} smooth pairs of {pairs}");
        // Some smooth lanes face away from their lobe (the VPL sends nothing there).
        assert!(dark > 0, "no smooth lane was dropped");
    }

    /// [`VplLanes::each_unshadowed`] reports, for the lanes asked for, exactly the VPLs and the
    /// bits [`Prepared::unshadowed`] gives one VPL at a time: eight-lane sets of diffuse and
    /// smooth Lambertian VPLs, a short set, and a set with a spot VPL (the general kernels).
    #[test]
    fn vpl_lanes_give_each_vpl_what_it_gives_alone() {
        let (scene, accel, camera, gbuf) = traced(matte_sphere(), (24, 24), 1);
        let (all, _) = Sir::new(4).sample(&scene, &accel, &camera, 1024, 9);
        // Sets of eight with smooth VPLs among them, a set of five, and a set with a spot.
        let smooth: Vec<usize> = (0..all.len()).filter(|&i| lambert_lobe(&all, i).is_some()).collect();
        let plain: Vec<usize> = (0..all.len()).filter(|&i| all.lobe[i] == crate::vpl::set::NO_LOBE).collect();
        assert!(smooth.len() >= 8 && plain.len() >= 8);
        let pick = |ids: &[usize]| {
            let mut set = VplSet::default();
            for &i in ids {
                set.push(crate::vpl::set::Vpl {
                    position: all.position[i],
                    normal: all.normal[i],
                    radiance: all.radiance[i],
                    lobe: match all.lobe[i] {
                        crate::vpl::set::NO_LOBE => None,
                        l => Some(all.lobes[l as usize]),
                    },
                    count: 1,
                    flags: all.flags[i],
                    length: all.length[i],
                    group: 0,
                });
            }
            set
        };
        let mixed = [smooth[0], plain[0], smooth[1], plain[1], plain[2], smooth[2], plain[3], smooth[3]];
        let mut with_spot = pick(&plain[..7]);
        let spot = Vec3::new(2.0, 4.5, 2.5);
        with_spot.push(crate::vpl::set::Vpl {
            position: spot,
            normal: Vec3::ZERO,
            radiance: Vec3::splat(3.0),
            lobe: Some(VplLobe::Spot { axis: -Vec3::Y, cos_inner: 0.9, cos_outer: 0.5 }),
            count: 1,
            flags: crate::vpl::set::ON_LIGHT,
            length: 0,
            group: 0,
        });
        let mut reported = 0;
        for (set, eight_lane) in
            [(pick(&mixed), true), (pick(&smooth[4..12]), true), (pick(&plain[..5]), true), (with_spot, false)]
        {
            let lanes = VplLanes::new(&set);
            assert_eq!(lanes.chunk.is_some(), eight_lane);
            for r in gbuf.receivers.iter().flatten() {
                let pt = Prepared::new(&scene, r);
                for active in [0xff, 0b1010_0101, 0b1] {
                    let mut got = Vec::new();
                    lanes.each_unshadowed(&set, &pt, r, active, 0.05, |j, c| {
                        got.push((j, c, pt.origin_towards(set.position[j]), set.position[j]))
                    });
                    let want: Vec<_> = (0..set.len())
                        .filter(|&j| active >> j & 1 != 0)
                        .filter_map(|j| pt.unshadowed(r, &set, j, 0.05).map(|(c, o, t)| (j, c, o, t)))
                        .collect();
                    assert_eq!(got, want);
                    reported += got.len();
                }
            }
        }
        assert!(reported > 1_000, "only {reported} contributions");
    }

    /// The Lambertian receivers' compensation rays ([`Prepared::compensation_ray`]) have the
    /// distribution of the general BSDF-sampled ones ([`Compensation::sample_ray`]): for flat
    /// walls and a smooth-shaded sphere (shading normal ≠ geometric normal, where the two side
    /// tests matter), the means of the weight, of weight × direction and of weight × cos θ_x
    /// agree within 4.5 standard errors, receiver by receiver; the origin is the one
    /// `offset_origin` gives for the direction.
    #[test]
    fn lambertian_compensation_rays_are_distributed_as_the_bsdf_samples() {
        let (scene, accel, _, gbuf) = traced(matte_sphere(), (24, 24), 5);
        let comp = super::super::compensate::Compensation { scene: &scene, accel: &accel, g_max: 1.0, min_d2: 0.0 };
        let mut checked = 0;
        let mut smooth = 0;
        // Directions each way rejects (below the shading horizon or the geometric one), summed.
        let (mut rejected, mut draws) = ((0u64, 0u64), 0u64);
        // Every smooth-shaded receiver, and one flat one in ten.
        let is_smooth = |r: &Receiver| r.bsdf.frame.n.dot(r.sp.ng).abs() < 0.9999;
        let all: Vec<&Receiver> = gbuf.receivers.iter().flatten().collect();
        let picked = all.iter().enumerate().filter(|(i, r)| is_smooth(r) || i % 10 == 0);
        for (_, &r) in picked.take(80) {
            let pt = Prepared::new(&scene, r);
            assert!(pt.lambert.is_some(), "matte scene");
            smooth += usize::from(is_smooth(r));
            // Per sample: weight luminance, and that times dir.x, dir.y, dir.z, cos θ_x.
            let moments = |fast: bool, seed: u64| {
                let mut sampler = IndependentSampler::new(seed);
                let n = 20_000;
                let (mut sum, mut sq) = ([0.0f64; 5], [0.0f64; 5]);
                let mut rejected = 0u64;
                for _ in 0..n {
                    let ray = if fast {
                        pt.compensation_ray(&mut sampler).unwrap()
                    } else {
                        comp.sample_ray(r, &mut sampler)
                    };
                    let Some(ray) = ray else {
                        rejected += 1;
                        continue;
                    };
                    if fast {
                        let o = offset_origin(&r.sp, &scene.mesh.corners(r.sp.tri), ray.dir);
                        assert_eq!(ray.origin, o);
                    }
                    let w = luminance(ray.weight) as f64;
                    let v = [w, w * ray.dir.x as f64, w * ray.dir.y as f64, w * ray.dir.z as f64, w * ray.cos_x as f64];
                    for k in 0..5 {
                        sum[k] += v[k];
                        sq[k] += v[k] * v[k];
                    }
                }
                let nf = n as f64;
                let m = std::array::from_fn::<(f64, f64), 5, _>(|k| {
                    let m = sum[k] / nf;
                    (m, ((sq[k] / nf - m * m).max(0.0) / nf).sqrt())
                });
                (m, rejected)
            };
            let ((a, rej_a), (b, rej_b)) = (moments(true, 1), moments(false, 2));
            rejected.0 += rej_a;
            rejected.1 += rej_b;
            draws += 20_000;
            for k in 0..5 {
                // (The weight ρ·β has no variance: its rounding, 10⁻⁶, is the floor.)
                let se = (a[k].1 * a[k].1 + b[k].1 * b[k].1).sqrt().max(1e-6 * a[k].0.abs()).max(1e-9);
                let z = (a[k].0 - b[k].0) / se;
                assert!(z.abs() < 4.5, "receiver at {:?}, moment {k}: {} vs {} (z {z:.1})", r.sp.p, a[k].0, b[k].0);
            }
            checked += 1;
        }
        assert!(checked >= 40 && smooth >= 20, "{checked} receivers, {smooth} smooth-shaded");
        // The same rejection rate (binomial z), and some rejections to compare.
        let (pa, pb) = (rejected.0 as f64 / draws as f64, rejected.1 as f64 / draws as f64);
        let p = 0.5 * (pa + pb);
        let z = (pa - pb) / (2.0 * p * (1.0 - p) / draws as f64).sqrt();
        assert!(rejected.1 > 50 && z.abs() < 4.5, "rejected {rejected:?} of {draws} each (z {z:.1})");
    }

    /// Regional VPLs ([`Interleave::regional`]) keep every pixel's expectation: averaged over
    /// every rotation of the split (the frame's random rotation is uniform over them), a gather
    /// with regional VPLs equals the gather of every VPL at every pixel (1×1), pixel by pixel,
    /// for regions of a subset's size, of a few pixels, or of nothing; a VPL whose region is the
    /// whole image stays in the split (a region larger than a subset's pixels would cost more
    /// shadow rays than the interleaved gather). A gather that weighted a region's pixels by the
    /// subset scale, or skipped the home subset outside the region, would be off by the VPL's
    /// light there.
    #[test]
    fn regional_vpls_average_over_rotations_to_the_full_gather() {
        let (w, h) = (48u32, 40u32);
        let (scene, accel, camera, gbuf) = traced(builtin::cornell(), (w, h), 7);
        let (mut vpls, _) = Sir::new(4).sample(&scene, &accel, &camera, 256, 11);
        assert!(vpls.len() >= 128);
        // 128 groups: two per subset of the 8×8 split, so every scale is exactly 64.
        vpls.group = (0..vpls.len() as u32).map(|i| i % 128).collect();
        vpls.groups = 128;
        vpls.footprint = vec![0.0; vpls.len()];
        vpls.footprint_rect = (0..vpls.len())
            .map(|i| match i % 4 {
                // 30 pixels: a subset's share of the 48×40 image.
                0 => [0, 0, 4, 5],
                1 => [w / 3, h / 4, w / 3 + 4, h / 4 + 4],
                2 => [u32::MAX, u32::MAX, 0, 0],
                _ => [0, 0, w - 1, h - 1],
            })
            .collect();
        let inter = Interleave::for_image(&vpls, 8, 8, (w, h));
        // An eighth of the groups (all of footprint 0, so the first 16 in order) among those
        // whose regions are no larger than a subset's pixels (group g holds VPLs g and g + 128,
        // both with region kind g mod 4).
        let flagged: Vec<u32> = (0..128).filter(|g| g % 4 != 3).take(16).collect();
        assert_eq!(inter.regional.len(), vpls.group.iter().filter(|g| flagged.contains(g)).count());
        assert!(inter.regional.iter().all(|r| r.vpl % 4 != 3), "a whole-image region is never regional");
        let mut st = RayStats::default();
        let g_max = 0.5;
        let (full, _) =
            gather(&scene, &accel, &gbuf, &vpls, &Interleave::new(&vpls, 1, 1), g_max, 0.0, Tracing::Single, &mut st);
        let mut mean = vec![Vec3::ZERO; full.len()];
        for k in 0..64 {
            let (img, _) =
                gather(&scene, &accel, &gbuf, &vpls, &inter.clone().rotated(k), g_max, 0.0, Tracing::Single, &mut st);
            mean.iter_mut().zip(&img).for_each(|(m, p)| *m += *p / 64.0);
        }
        let scale = full.iter().map(|p| p.max_element()).sum::<f32>() / full.len() as f32;
        for (i, (a, b)) in mean.iter().zip(&full).enumerate() {
            assert!((*a - *b).abs().max_element() <= 1e-4 * (b.max_element() + scale), "pixel {i}: {a} vs {b}");
        }
    }
}
