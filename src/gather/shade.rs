//! The gather proper: every pixel sums the contributions `L·f·G·V` of its VPL subset, with G
//! clamped at the bound of `--clamp` (0: no clamp, unbiased). Clamping is reported honestly:
//! the luminance the clamp removed is summed alongside what was kept.

use glam::Vec3;
use rayon::prelude::*;

use super::gbuffer::GBuffer;
use super::interleave::Interleave;
use crate::accel::Accel;
use crate::color::luminance;
use crate::scene::Scene;
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

/// Gathers `vpls` into an image of VPL-transported light (emission seen directly is not
/// included; see [`GBuffer::emitted`]).
pub fn gather(
    scene: &Scene,
    accel: &Accel,
    gbuf: &GBuffer,
    vpls: &VplSet,
    inter: &Interleave,
    g_max: f32,
    min_distance: f32,
    stats: &mut RayStats,
) -> (Vec<Vec3>, GatherEnergy) {
    let min_d2 = min_distance * min_distance;
    let w = gbuf.width;
    let rows: Vec<(Vec<Vec3>, RayStats, GatherEnergy)> = (0..gbuf.height)
        .into_par_iter()
        .map(|y| {
            let mut st = RayStats::default();
            let mut energy = GatherEnergy::default();
            let row = (0..w)
                .map(|x| {
                    let Some(r) = &gbuf.receivers[(y * w + x) as usize] else { return Vec3::ZERO };
                    let k = inter.subset_of(x, y);
                    let mut sum = Vec3::ZERO;
                    let mut removed = Vec3::ZERO;
                    for &i in &inter.subsets[k] {
                        let i = i as usize;
                        if min_d2 > 0.0 && (vpls.position[i] - r.sp.p).length_squared() < min_d2 {
                            continue;
                        }
                        let Some((c, full)) = unshadowed(vpls, i, r, g_max) else { continue };
                        let (o, d) = shadow_segment(scene, vpls, i, r);
                        st.shadow += 1;
                        if accel.occluded(o, d, SHADOW_T_MAX) {
                            continue;
                        }
                        sum += c;
                        removed += full - c;
                    }
                    let s = inter.scales[k];
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
