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
use crate::accel::batch::ShadowBatch;
use crate::accel::single::NO_OCCLUDER;
use crate::color::luminance;
use crate::sampling::IndependentSampler;
use crate::scene::Scene;
use crate::simd::{F8, LaneRay, Lanes, RayPacket};
use crate::stats::RayStats;
use crate::vpl::VplSet;
use crate::vpl::kernel::{Prepared, VplChunk, chunkable};
use crate::vpl::transfer::{Receiver, SHADOW_T_MAX, shadow_segment, unshadowed};
use std::f32::consts::PI;

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
    /// Per VPL, the luminance it brought to the image (for [`power_ratio`]); empty: not kept.
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

/// The VPLs of every interleave subset, eight to a chunk, in subset order.
fn chunk_subsets(vpls: &VplSet, inter: &Interleave) -> Vec<Vec<VplChunk>> {
    inter.subsets.iter().map(|subset| subset.chunks(F8::LANES).map(|ids| VplChunk::new(vpls, ids)).collect()).collect()
}

/// The clamp compensation's part of a prepared receiver, beside the compensation it serves (the
/// kernels below the gather do not know it).
impl Prepared {
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
    /// the row (compensation excluded; for [`power_ratio`]).
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
mod tests;
