//! The gather proper: every pixel sums the contributions `L·f·G·V` of its VPL subset, with G
//! clamped at the bound of `--clamp` (0: no clamp, unbiased). Clamping is reported honestly:
//! the luminance the clamp removed is summed alongside what was kept.

use glam::Vec3;
use rayon::prelude::*;

use super::Tracing;
use super::gbuffer::GBuffer;
use super::interleave::Interleave;
use crate::accel::Accel;
use crate::color::luminance;
use crate::scene::Scene;
use crate::simd::{F8, LaneRay, Lanes, RayPacket};
use crate::stats::RayStats;
use crate::vpl::VplSet;
use crate::vpl::transfer::{SHADOW_T_MAX, shadow_segment, unshadowed};

/// Energy bookkeeping of one gather.
#[derive(Clone, Copy, Debug, Default)]
pub struct GatherEnergy {
    /// Sum of the luminance of kept (clamped) contributions.
    pub kept: f64,
    /// Sum of the luminance the clamp removed.
    pub removed: f64,
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
    }
}

/// A shadow ray still to trace: pixel x of the row, clamped and unclamped contributions, segment.
type Pending = (u32, Vec3, Vec3, Vec3, Vec3);

/// Per-row accumulation of contributions that pass their shadow rays.
struct RowSums {
    sum: Vec<Vec3>,
    removed: Vec<Vec3>,
    pending: Vec<Pending>,
}

impl RowSums {
    fn add(&mut self, (x, c, full, _, _): Pending) {
        self.sum[x as usize] += c;
        self.removed[x as usize] += full - c;
    }

    /// Traces the pending shadow rays as one packet (a lone ray as a single ray).
    fn flush(&mut self, accel: &Accel, st: &mut RayStats) {
        st.shadow += self.pending.len() as u64;
        let mut pending = std::mem::take(&mut self.pending);
        if let [(_, _, _, o, d)] = pending[..] {
            if !accel.occluded(o, d, SHADOW_T_MAX) {
                self.add(pending[0]);
            }
        } else if !pending.is_empty() {
            let packet = RayPacket::<F8>::from_fn(|j| pending.get(j).map(|p| LaneRay::new(p.3, p.4, SHADOW_T_MAX)));
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
    let min_d2 = min_distance * min_distance;
    let w = gbuf.width;
    // The shadow ray from pixel x of row y to VPL i, with its contributions (None: nothing to
    // trace — no receiver, too close, or zero unshadowed contribution).
    let candidate = |x: u32, y: u32, i: usize| -> Option<Pending> {
        let r = gbuf.receivers[(y * w + x) as usize].as_ref()?;
        if min_d2 > 0.0 && (vpls.position[i] - r.sp.p).length_squared() < min_d2 {
            return None;
        }
        let (c, full) = unshadowed(vpls, i, r, g_max)?;
        let (o, d) = shadow_segment(scene, vpls, i, r);
        Some((x, c, full, o, d))
    };
    let rows: Vec<(Vec<Vec3>, RayStats, GatherEnergy)> = (0..gbuf.height)
        .into_par_iter()
        .map(|y| {
            let mut st = RayStats::default();
            let mut acc = RowSums {
                sum: vec![Vec3::ZERO; w as usize],
                removed: vec![Vec3::ZERO; w as usize],
                pending: Vec::with_capacity(F8::LANES),
            };
            match tracing {
                Tracing::Single | Tracing::PrimaryPackets => {
                    for x in 0..w {
                        for &i in &inter.subsets[inter.subset_of(x, y)] {
                            if let Some(p) = candidate(x, y, i as usize) {
                                st.shadow += 1;
                                if !accel.occluded(p.3, p.4, SHADOW_T_MAX) {
                                    acc.add(p);
                                }
                            }
                        }
                    }
                }
                Tracing::SharedOrigin => {
                    for x in 0..w {
                        for &i in &inter.subsets[inter.subset_of(x, y)] {
                            if let Some(p) = candidate(x, y, i as usize) {
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
                                    if let Some(p) = candidate(x, y, i as usize) {
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
            let row = (0..w)
                .map(|x| {
                    let s = inter.scales[inter.subset_of(x, y)];
                    let (sum, removed) = (acc.sum[x as usize], acc.removed[x as usize]);
                    energy.kept += (luminance(sum) * s) as f64;
                    energy.removed += (luminance(removed) * s) as f64;
                    sum * s
                })
                .collect();
            (row, st, energy)
        })
        .collect();
    let mut out = Vec::with_capacity((w * gbuf.height) as usize);
    let mut energy = GatherEnergy::default();
    for (row, st, e) in rows {
        out.extend(row);
        *stats += st;
        energy += e;
    }
    (out, energy)
}
