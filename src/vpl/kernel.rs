//! The VPL-to-receiver kernels shared by the gather and MIR's probe normalisation: a receiver
//! prepared once per pixel ([`Prepared`]), its Lambertian fast path, and eight VPLs of a set in
//! SIMD lanes ([`VplChunk`], [`VplLanes`]), each with the bits of the general kernels in
//! [`super::transfer`] (tests in `gather/shade/tests.rs`, over traced G-buffers).

use std::f32::consts::FRAC_1_PI;

use glam::Vec3;

use super::set::VplLobe;
use super::transfer::{Receiver, unshadowed};
use super::{TWO_SIDED, VplSet};
use crate::accel::ray_offset;
use crate::bsdf::BsdfKind;
use crate::scene::Scene;
use crate::simd::{F8, Lanes};

/// A G-buffer receiver prepared for the gather's inner loop: the parts of
/// [`unshadowed`] and [`shadow_segment`] that depend on the receiver alone, computed once per
/// pixel instead of once per VPL–pixel pair.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Prepared {
    pub(crate) p: Vec3,
    /// Front geometric normal and the origin offset along it ([`crate::accel::ray_offset`]).
    pub(crate) ng: Vec3,
    pub(crate) offset: f32,
    /// Set for a Lambertian receiver (the common case): the diffuse fast path.
    pub(crate) lambert: Option<LambertReceiver>,
}

/// The factors of a Lambertian receiver's `β · f(wo, wi) · |cos θ_i|` that do not depend on wi.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LambertReceiver {
    /// The BSDF's geometric normal (oriented towards wo) and `wo · ng_o`.
    pub(crate) ng_o: Vec3,
    pub(crate) wo_ng: f32,
    /// The shading normal and `wo · n_s`.
    pub(crate) ns: Vec3,
    pub(crate) wo_ns: f32,
    /// ρ/π.
    pub(crate) f: Vec3,
    pub(crate) beta: Vec3,
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
    pub(crate) fn unshadowed(&self, set: &VplSet, i: usize, p: Vec3, g_max: f32) -> Option<(Vec3, Vec3)> {
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
pub(crate) struct VplChunk {
    /// VPL index of each lane.
    pub(crate) index: [u32; 8],
    /// Lanes holding a VPL (low bits).
    pub(crate) lanes: u32,
    pub(crate) position: [F8; 3],
    pub(crate) normal: [F8; 3],
    /// Diffuse lanes: the radiance; smooth lanes: `r · ρ/π` (the lobe's factor times its BSDF
    /// value on the reflecting side).
    pub(crate) radiance: [F8; 3],
    /// Masks: the VPL is punctual (zero normal, cosine 1); it emits on both sides.
    pub(crate) punctual: F8,
    pub(crate) two_sided: F8,
    /// Smooth lanes: the mask, the lobe's shading normal and geometric normal, and `wo·n_s`,
    /// `wo·n_g` for its `wo` (zero in diffuse lanes).
    pub(crate) smooth: F8,
    pub(crate) smooth_lanes: u32,
    pub(crate) lobe_ns: [F8; 3],
    pub(crate) lobe_ng: [F8; 3],
    pub(crate) wo_ns: F8,
    pub(crate) wo_ng: F8,
}

/// The albedo, BSDF and `wo` of VPL `i`'s lobe when it is a Lambertian surface (None: a diffuse
/// VPL, or another lobe).
pub(crate) fn lambert_lobe(vpls: &VplSet, i: usize) -> Option<(Vec3, &crate::bsdf::Bsdf, Vec3)> {
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
pub(crate) fn chunkable(vpls: &VplSet) -> bool {
    vpls.all_diffuse()
        || (0..vpls.len()).all(|i| vpls.lobe[i] == crate::vpl::set::NO_LOBE || lambert_lobe(vpls, i).is_some())
}

impl VplChunk {
    /// The VPLs `ids` (at most eight, each diffuse or with a Lambertian lobe) of `vpls` in lanes.
    pub(crate) fn new(vpls: &VplSet, ids: &[u32]) -> Self {
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
    pub(crate) chunk: Option<VplChunk>,
    pub(crate) len: usize,
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
pub(crate) struct LaneContributions {
    pub(crate) lanes: u32,
    /// Per lane: the clamped contribution's r, g, b, then the unclamped one's (transposed from
    /// the kernel's channel vectors, so a lane is read from one store: read across the channel
    /// arrays, its values were merged into one wide load spanning two stores still in flight,
    /// which stalled the gather).
    pub(crate) by_lane: [[f32; 8]; 8],
}

impl LaneContributions {
    /// The clamped and unclamped contribution of lane `j`.
    #[inline(always)]
    pub(crate) fn lane(&self, j: usize) -> (Vec3, Vec3) {
        let v = &self.by_lane[j];
        (Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]))
    }
}

impl LambertReceiver {
    /// [`LambertReceiver::unshadowed`] for the eight VPLs of `ch` at once, lane for lane the
    /// same operations (no fused multiply-adds), so the same bits; lanes closer than
    /// `min_d2` (squared) are dropped as the scalar gather drops them.
    #[inline(always)]
    pub(crate) fn unshadowed8(&self, ch: &VplChunk, p: Vec3, g_max: f32, min_d2: f32) -> LaneContributions {
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
