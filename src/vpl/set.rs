//! The VPL set: structure-of-arrays storage the gather reads in tight loops.
//!
//! A VPL at point y with normal n emits, towards a receiving point x in direction w = (x − y)/|x − y|,
//! the "radiance" `radiance(i, w)`; its contribution to x is
//! `radiance(i, w) · cos_v · f(x) · cos_x / d² · V` with `cos_v = max(0, n·w)` (taken as 1 for
//! point and spot lights, whose normal is zero). Two-sided emitters use |n·w|.
//!
//! Most VPLs are diffuse: their radiance does not depend on w and is stored directly. VPLs on
//! glossy surfaces or with shading normals, and spot lights, keep a [`VplLobe`] that is
//! evaluated per direction, so every BSDF is "evaluated as it is" (issue 5).

use glam::Vec3;

use crate::bsdf::Bsdf;
use crate::path::shading_correction;
use crate::scene::emitter::spot_falloff;

/// VPL flag: the VPL lies on a light source.
pub const ON_LIGHT: u8 = 1;
/// VPL flag: emits on both sides of its surface.
pub const TWO_SIDED: u8 = 2;

/// Marker for "no lobe": the VPL is diffuse.
pub const NO_LOBE: u32 = u32::MAX;

/// Direction dependence of a non-diffuse VPL.
#[derive(Clone, Copy, Debug)]
pub enum VplLobe {
    /// A surface vertex of a light path: radiance(w) = stored · f(wo → w) · (shading-normal
    /// correction for importance transport).
    Surface {
        /// The BSDF at the vertex.
        bsdf: Bsdf,
        /// Direction towards the previous light-path vertex.
        wo: Vec3,
    },
    /// A spot light: radiance(w) = stored · falloff(axis · w).
    Spot {
        /// Unit spot axis.
        axis: Vec3,
        /// Cosine of the inner cone.
        cos_inner: f32,
        /// Cosine of the outer cone.
        cos_outer: f32,
    },
}

/// A set of virtual point lights.
#[derive(Clone, Debug, Default)]
pub struct VplSet {
    /// Positions.
    pub position: Vec<Vec3>,
    /// Unit normals of the emitting side (zero for point and spot lights).
    pub normal: Vec<Vec3>,
    /// RGB radiance of diffuse VPLs, or the factor multiplying the lobe.
    pub radiance: Vec<Vec3>,
    /// Lobe index into `lobes`, or [`NO_LOBE`].
    pub lobe: Vec<u32>,
    /// Number of light paths merged into this VPL (MIR's k; 1 otherwise).
    pub count: Vec<u32>,
    /// [`ON_LIGHT`], [`TWO_SIDED`] flags.
    pub flags: Vec<u8>,
    /// Number of edges of the light sub-path ending at the VPL (0 on a light).
    pub length: Vec<u8>,
    /// Independent-sample group (light path, chain state...) for interleaving.
    pub group: Vec<u32>,
    /// Lobes of non-diffuse VPLs.
    pub lobes: Vec<VplLobe>,
    /// Number of groups.
    pub groups: u32,
    /// Share of the image's camera rays that see each VPL (MIR's probe estimate), or empty
    /// when unknown. The gather spreads a VPL that would light very few pixels of its
    /// interleave subset over every pixel of its screen region instead
    /// ([`crate::gather::Interleave::for_image`]).
    pub footprint: Vec<f32>,
    /// Each VPL's screen region, `[x0, y0, x1, y1]` (pixels, inclusive): where the probes that
    /// saw it lie, widened by the probes' spacing (MIR), or empty when unknown (the whole
    /// image). Only where the gather spends rays: a VPL is gathered outside it too.
    pub footprint_rect: Vec<[u32; 4]>,
}

/// One VPL for [`VplSet::push`].
#[derive(Clone, Copy, Debug)]
pub struct Vpl {
    /// Position.
    pub position: Vec3,
    /// Emitting-side normal (zero for punctual lights).
    pub normal: Vec3,
    /// Radiance (diffuse) or lobe factor.
    pub radiance: Vec3,
    /// Optional lobe.
    pub lobe: Option<VplLobe>,
    /// Path count k.
    pub count: u32,
    /// Flags.
    pub flags: u8,
    /// Light sub-path length.
    pub length: u8,
    /// Group.
    pub group: u32,
}

impl Vpl {
    /// [`VplSet::radiance`] of this VPL.
    #[inline]
    pub fn radiance_towards(&self, w: Vec3) -> Vec3 {
        emitted(self.radiance, self.lobe.as_ref(), w)
    }

    /// [`VplSet::cos_at`] of this VPL.
    #[inline]
    pub fn cos_at(&self, w: Vec3) -> f32 {
        cos_factor(self.normal, self.flags, w)
    }
}

/// Radiance of a VPL with radiance factor `r` and `lobe` along `w`.
#[inline]
fn emitted(r: Vec3, lobe: Option<&VplLobe>, w: Vec3) -> Vec3 {
    match lobe {
        None => r,
        Some(VplLobe::Surface { bsdf, wo }) => r * bsdf.f(*wo, w) * shading_correction(bsdf, *wo, w),
        Some(VplLobe::Spot { axis, cos_inner, cos_outer }) => r * spot_falloff(axis.dot(w), *cos_inner, *cos_outer),
    }
}

/// The cosine factor at a VPL with normal `n` and `flags` for direction `w`.
#[inline]
fn cos_factor(n: Vec3, flags: u8, w: Vec3) -> f32 {
    if n == Vec3::ZERO {
        return 1.0;
    }
    let c = n.dot(w);
    if flags & TWO_SIDED != 0 { c.abs() } else { c.max(0.0) }
}

impl VplSet {
    /// Number of VPLs.
    pub fn len(&self) -> usize {
        self.position.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.position.is_empty()
    }

    /// Appends a VPL.
    pub fn push(&mut self, v: Vpl) {
        self.position.push(v.position);
        self.normal.push(v.normal);
        self.radiance.push(v.radiance);
        self.lobe.push(match v.lobe {
            Some(l) => {
                self.lobes.push(l);
                self.lobes.len() as u32 - 1
            }
            None => NO_LOBE,
        });
        self.count.push(v.count);
        self.flags.push(v.flags);
        self.length.push(v.length);
        self.group.push(v.group);
        self.groups = self.groups.max(v.group + 1);
    }

    /// Multiplies every VPL's radiance by `s`.
    pub fn scale(&mut self, s: f32) {
        for r in &mut self.radiance {
            *r *= s;
        }
    }

    /// True when every VPL is diffuse (no lobes): the gather can take its fast path.
    pub fn all_diffuse(&self) -> bool {
        self.lobes.is_empty()
    }

    /// Radiance VPL `i` emits along unit direction `w` (not including the cosine at the VPL).
    #[inline]
    pub fn radiance(&self, i: usize, w: Vec3) -> Vec3 {
        let lobe = match self.lobe[i] {
            NO_LOBE => None,
            l => Some(&self.lobes[l as usize]),
        };
        emitted(self.radiance[i], lobe, w)
    }

    /// The cosine factor at VPL `i` for direction `w`: max(0, n·w), |n·w| when two-sided, 1 for
    /// punctual lights.
    #[inline]
    pub fn cos_at(&self, i: usize, w: Vec3) -> f32 {
        cos_factor(self.normal[i], self.flags[i], w)
    }

    /// VPL `i`.
    pub fn get(&self, i: usize) -> Vpl {
        Vpl {
            position: self.position[i],
            normal: self.normal[i],
            radiance: self.radiance[i],
            lobe: match self.lobe[i] {
                NO_LOBE => None,
                l => Some(self.lobes[l as usize]),
            },
            count: self.count[i],
            flags: self.flags[i],
            length: self.length[i],
            group: self.group[i],
        }
    }

    /// Appends all VPLs of `other`, offsetting its groups.
    pub fn append(&mut self, other: &VplSet) {
        let base = self.groups;
        for i in 0..other.len() {
            self.push(Vpl { group: base + other.group[i], ..other.get(i) });
        }
        self.groups = base + other.groups;
    }
}
