//! Path vertices with the cached quantities of bidirectional estimators: throughput `beta`
//! (α^L or α^E of papers/000 Appendix A) and the forward / reverse densities of the vertex in
//! area measure (Veach 1997 §10.2; pbrt-v3 §16.3).
//!
//! Conventions: `pdf_fwd` is the density (area measure) with which the walk that built the
//! path generated this vertex; `pdf_rev` is the density with which a walk coming from the other
//! end would have generated it. A vertex after a delta (specular) scattering event has both set
//! to 0 and `delta = true`; MIS treats those as "cannot be connected" (papers/000 §4.3).

use glam::{Vec2, Vec3};

use crate::bsdf::{Bsdf, TransportMode};
use crate::scene::{Light, NO_LIGHT, Scene};

/// Marker for "no triangle" in [`Vertex::tri`].
pub const NO_TRI: u32 = u32::MAX;

/// What a vertex lies on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VertexKind {
    /// The camera lens.
    Camera,
    /// A light source (start of a light sub-path, or a light point chosen by NEE).
    Light,
    /// A scene surface (possibly emissive).
    Surface,
}

/// One vertex of a camera or light sub-path.
///
/// A vertex on a light at infinity (the sun, the sky: [`Vertex::at_infinity`]) lies beyond the
/// bounding sphere in its direction (a light sub-path's first vertex on the disk it starts
/// from, a camera path's escape or a next-event sample at [`Scene::far_point`]); it has no
/// normal (`ng` zero), `ns` holds the unit direction from the scene towards the light, and
/// densities and the geometry term at it are in solid angle (pbrt-v3 §16.3: no 1/d², no cosine).
#[derive(Clone, Copy, Debug)]
pub struct Vertex {
    /// Kind.
    pub kind: VertexKind,
    /// Position.
    pub p: Vec3,
    /// Geometric normal: the winding normal on surfaces, the emitting face on area lights, the
    /// viewing direction on the camera, zero on point and spot lights and at infinity.
    pub ng: Vec3,
    /// Shading normal (same side as `ng`); at infinity, the direction towards the light.
    pub ns: Vec3,
    /// Texture coordinates.
    pub uv: Vec2,
    /// Triangle index, or [`NO_TRI`].
    pub tri: u32,
    /// Light index for light vertices and for surface vertices on emitters, else `NO_LIGHT`.
    pub light: u32,
    /// Direction towards the previous vertex of the walk that built this vertex.
    pub wo: Vec3,
    /// BSDF of surface vertices.
    pub bsdf: Option<Bsdf>,
    /// Throughput of the sub-path up to and including this vertex.
    pub beta: Vec3,
    /// The BSDF sampled here was a delta distribution (or the light is a point/spot light).
    pub delta: bool,
    /// Area density of generating this vertex along the walk.
    pub pdf_fwd: f32,
    /// Area density of generating this vertex from the other end.
    pub pdf_rev: f32,
    /// On a light at infinity (see the type's doc).
    pub at_infinity: bool,
}

impl Vertex {
    /// The camera vertex at a lens point.
    pub fn camera(p: Vec3, forward: Vec3, beta: Vec3, pdf_pos: f32) -> Vertex {
        Vertex {
            kind: VertexKind::Camera,
            p,
            ng: forward,
            ns: forward,
            uv: Vec2::ZERO,
            tri: NO_TRI,
            light: NO_LIGHT,
            wo: Vec3::ZERO,
            bsdf: None,
            beta,
            delta: false,
            pdf_fwd: pdf_pos,
            pdf_rev: 0.0,
            at_infinity: false,
        }
    }

    /// A vertex on the lights at infinity in direction `wi` (from the scene towards them), at
    /// `p` beyond the bounding sphere: `light` is the light it was sampled on (for a camera
    /// path's escape, any of the lights a ray can meet: its radiance is theirs together,
    /// [`Scene::escaped`]).
    pub fn at_infinity(light: u32, p: Vec3, wi: Vec3, beta: Vec3, pdf_fwd: f32) -> Vertex {
        Vertex {
            kind: VertexKind::Light,
            p,
            ng: Vec3::ZERO,
            ns: wi,
            uv: Vec2::ZERO,
            tri: NO_TRI,
            light,
            wo: Vec3::ZERO,
            bsdf: None,
            beta,
            delta: false,
            pdf_fwd,
            pdf_rev: 0.0,
            at_infinity: true,
        }
    }

    /// A light vertex (emitting-face normal `n`, zero for point and spot lights).
    pub fn light(scene: &Scene, light: u32, p: Vec3, n: Vec3, beta: Vec3, pdf_pos: f32) -> Vertex {
        let tri = match scene.lights.list[light as usize] {
            Light::Area { tri, .. } => tri,
            _ => NO_TRI,
        };
        Vertex {
            kind: VertexKind::Light,
            p,
            ng: n,
            ns: n,
            uv: Vec2::ZERO,
            tri,
            light,
            wo: Vec3::ZERO,
            bsdf: None,
            beta,
            delta: false,
            pdf_fwd: pdf_pos,
            pdf_rev: 0.0,
            at_infinity: false,
        }
    }

    /// True for vertices on a surface (surfaces and area lights), where cosines apply.
    #[inline]
    pub fn on_surface(&self) -> bool {
        self.ng != Vec3::ZERO && self.kind != VertexKind::Camera
    }

    /// True for vertices on a light no ray can hit: a point or spot light, or a delta sun.
    #[inline]
    pub fn is_delta_light(&self) -> bool {
        self.kind == VertexKind::Light && self.tri == NO_TRI && (!self.at_infinity || self.delta)
    }

    /// True when a deterministic connection can end at this vertex (never at infinity: only a
    /// sampled direction reaches it).
    #[inline]
    pub fn connectible(&self) -> bool {
        match self.kind {
            _ if self.at_infinity => false,
            VertexKind::Camera | VertexKind::Light => true,
            VertexKind::Surface => self.bsdf.is_some_and(|b| !b.is_delta()),
        }
    }

    /// True for light vertices and surface vertices on emitters.
    #[inline]
    pub fn is_light(&self) -> bool {
        self.kind == VertexKind::Light || (self.kind == VertexKind::Surface && self.light != NO_LIGHT)
    }

    /// BSDF value for scattering from `wo` towards `next` (zero for non-surfaces). For light
    /// sub-paths (`Importance`) the shading-normal adjoint correction is included
    /// (Veach 1997, §5.3).
    pub fn f(&self, next: &Vertex, mode: TransportMode) -> Vec3 {
        let Some(bsdf) = &self.bsdf else { return Vec3::ZERO };
        let Some(wi) = (next.p - self.p).try_normalize() else { return Vec3::ZERO };
        let f = bsdf.f(self.wo, wi);
        match mode {
            TransportMode::Radiance => f,
            TransportMode::Importance => f * shading_correction(bsdf, self.wo, wi),
        }
    }

    /// Converts a solid-angle density at this vertex towards `next` into an area density at
    /// `next` (`pdf_a = pdf_w |cos θ_next| / d²`).
    /// A vertex at infinity keeps the solid-angle density.
    #[inline]
    pub fn convert_density(&self, pdf_w: f32, next: &Vertex) -> f32 {
        if next.at_infinity {
            return pdf_w;
        }
        let w = next.p - self.p;
        let d2 = w.length_squared();
        if !(d2 > 0.0) {
            return 0.0;
        }
        let mut pdf = pdf_w / d2;
        if next.on_surface() {
            pdf *= (next.ng.dot(w) / d2.sqrt()).abs();
        }
        pdf
    }

    /// Area density at `next` of sampling it from this vertex, having arrived from `prev`
    /// (BSDF sampling on surfaces, importance sampling on the camera, emission on lights).
    pub fn pdf(&self, scene: &Scene, prev: Option<&Vertex>, next: &Vertex) -> f32 {
        match self.kind {
            VertexKind::Light => return self.pdf_light(scene, next),
            VertexKind::Camera => {
                let Some(w) = (next.p - self.p).try_normalize() else { return 0.0 };
                let (_, pdf_dir) = scene.camera.pdf_we(w);
                return self.convert_density(pdf_dir, next);
            }
            VertexKind::Surface => {}
        }
        let (Some(bsdf), Some(prev)) = (&self.bsdf, prev) else { return 0.0 };
        let (Some(wp), Some(wn)) = ((prev.p - self.p).try_normalize(), (next.p - self.p).try_normalize()) else {
            return 0.0;
        };
        self.convert_density(bsdf.pdf_w(wp, wn), next)
    }

    /// Area density at `next` with which this light (or emissive surface) vertex emits
    /// towards it. From infinity: the disk's area density 1/(πR²) times the cosine at `next`
    /// (the light's choice and direction are in this vertex's own density).
    pub fn pdf_light(&self, scene: &Scene, next: &Vertex) -> f32 {
        let light = self.light;
        if light == NO_LIGHT {
            return 0.0;
        }
        if self.at_infinity {
            let r = scene.bounding_sphere().1;
            let cos = if next.on_surface() { next.ng.dot(self.ns).abs() } else { 1.0 };
            return cos / (std::f32::consts::PI * r * r);
        }
        let Some(w) = (next.p - self.p).try_normalize() else { return 0.0 };
        self.convert_density(scene.pdf_light_direction(light, self.ng, w), next)
    }

    /// Area density with which a light sub-path starts at this (light or emissive) vertex. At
    /// infinity: the solid-angle density of its direction over all lights a ray meets there
    /// (light choice included), or the choice alone for a delta sun.
    pub fn pdf_light_origin(&self, scene: &Scene) -> f32 {
        if self.light == NO_LIGHT {
            return 0.0;
        }
        if self.at_infinity {
            return if self.delta {
                scene.lights.distribution.pmf(self.light as usize)
            } else {
                scene.pdf_li_escaped(self.ns)
            };
        }
        scene.pdf_light_position(self.light)
    }

    /// Radiance this surface vertex emits towards `to` (zero unless it is on an emitter); at
    /// infinity, the radiance of the lights there along its direction.
    pub fn le(&self, scene: &Scene, to: &Vertex) -> Vec3 {
        if self.at_infinity {
            return if self.delta { Vec3::ZERO } else { scene.escaped(self.ns) };
        }
        if self.kind != VertexKind::Surface || self.light == NO_LIGHT {
            return Vec3::ZERO;
        }
        let Some(w) = (to.p - self.p).try_normalize() else { return Vec3::ZERO };
        scene.emitted(self.tri, self.ng, self.uv, w)
    }
}

/// The factor that makes shading normals reciprocal for importance transport:
/// `|wo·ns| |wi·ng| / (|wo·ng| |wi·ns|)` (Veach 1997, eq. 5.20; pbrt-v3 §16.1).
#[inline]
pub fn shading_correction(bsdf: &Bsdf, wo: Vec3, wi: Vec3) -> f32 {
    let num = wo.dot(bsdf.frame.n).abs() * wi.dot(bsdf.ng).abs();
    let den = wo.dot(bsdf.ng).abs() * wi.dot(bsdf.frame.n).abs();
    if den == 0.0 { 0.0 } else { num / den }
}

/// The geometric term `|cos θ_a| |cos θ_b| / d²` between two vertices, with shading normals
/// on surfaces (visibility not included).
/// With one end at infinity, only the other end's cosine (solid-angle measure there).
#[inline]
pub fn geometry(a: &Vertex, b: &Vertex) -> f32 {
    if a.at_infinity || b.at_infinity {
        let (v, wi) = if a.at_infinity { (b, a.ns) } else { (a, b.ns) };
        return if v.on_surface() { v.ns.dot(wi).abs() } else { 1.0 };
    }
    let d = b.p - a.p;
    let d2 = d.length_squared();
    if !(d2 > 0.0) {
        return 0.0;
    }
    let w = d / d2.sqrt();
    let mut g = 1.0 / d2;
    if a.on_surface() {
        g *= a.ns.dot(w).abs();
    }
    if b.on_surface() {
        g *= b.ns.dot(w).abs();
    }
    g
}
