//! Complete light paths ȳ = y_0 … y_{k−1} (y_0 on a light, y_{k−1} on the lens) as the state of
//! path-space MLT, and their evaluation (Veach 1997 ch. 11; Fischer, docs/bibliography.md).
//!
//! A vertex holds only its position and surface: every direction, BSDF value and density is
//! recomputed from the neighbours, so a path spliced together by a mutation is evaluated the
//! same way as one walked in a single go.
//!
//! [`evaluate`] gives, for every way s = 0 … k of splitting ȳ into a light sub-path of s
//! vertices and a camera sub-path of t = k − s vertices, the unweighted contribution
//! `C*_{s,t}(ȳ) = f(ȳ) / p_{s,t}(ȳ)` of bidirectional path tracing (papers: Fischer Appendix A,
//! eq. 18), computed as BDPT computes it (`path::connect`): the light sub-path's throughput in
//! importance transport (with the shading-normal correction), the connection, the camera
//! sub-path's throughput in radiance transport. Their ratios are ratios of path densities with the
//! same f, which is all the mutations' acceptance probabilities need, and delta (specular)
//! scattering enters only through these ratios, never as f or p alone (Fischer §4.3). A strategy
//! that cannot produce ȳ (a connection at a specular vertex, t = 0, s = 0 on a point light) is
//! `None`.

use glam::{DVec3, Vec2, Vec3};

use crate::accel::{Accel, SHADOW_T_MAX, ray_offset};
use crate::bsdf::{Bsdf, BsdfKind, TransportMode, dielectric, mirror};
use crate::color::luminance;
use crate::path::{NO_TRI, shading_correction};
use crate::sampling::Pcg32;
use crate::sampling::warp::sample_uniform_triangle;
use crate::scene::{Light, NO_LIGHT, Scene, SurfacePoint};
use crate::stats::RayStats;

/// What a path vertex lies on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Node {
    /// The camera lens.
    Lens,
    /// A point or spot light.
    PointLight,
    /// A scene surface (an area light when `light` is set).
    Surface,
}

/// One vertex of a complete path.
#[derive(Clone, Copy, Debug)]
pub struct PathVertex {
    /// What it lies on.
    pub node: Node,
    /// Position, normals (zero off surfaces), texture coordinates and triangle.
    pub sp: SurfacePoint,
    /// The light it lies on (an emitter's index), or `NO_LIGHT`.
    pub light: u32,
    /// Scattering model of a surface vertex.
    pub kind: Option<BsdfKind>,
}

impl PathVertex {
    /// A lens vertex.
    pub fn lens(p: Vec3) -> Self {
        let sp = SurfacePoint { p, ng: Vec3::ZERO, ns: Vec3::ZERO, uv: Vec2::ZERO, tri: NO_TRI };
        PathVertex { node: Node::Lens, sp, light: NO_LIGHT, kind: None }
    }

    /// A vertex on a scene surface.
    pub fn surface(scene: &Scene, sp: SurfacePoint) -> Self {
        let kind = scene.material_of(sp.tri).bsdf_kind(sp.uv, &scene.textures);
        PathVertex { node: Node::Surface, light: scene.mesh.emitter[sp.tri as usize], kind: Some(kind), sp }
    }

    /// Position.
    #[inline]
    pub fn p(&self) -> Vec3 {
        self.sp.p
    }

    /// True on a mirror or dielectric.
    #[inline]
    pub fn is_specular(&self) -> bool {
        matches!(self.kind, Some(BsdfKind::Mirror { .. } | BsdfKind::Dielectric { .. }))
    }

    /// The BSDF seen from direction `wo`.
    #[inline]
    fn bsdf(&self, wo: Vec3) -> Option<Bsdf> {
        self.kind.map(|k| Bsdf::new(k, self.sp.ns, self.sp.ng, wo))
    }

    /// A ray origin just off the surface towards `dir`.
    fn origin_towards(&self, scene: &Scene, dir: Vec3) -> Vec3 {
        if self.node != Node::Surface {
            return self.sp.p;
        }
        let d = ray_offset(self.sp.p, &scene.mesh.corners(self.sp.tri));
        if self.sp.ng.dot(dir) >= 0.0 { self.sp.p + self.sp.ng * d } else { self.sp.p - self.sp.ng * d }
    }
}

/// Radiance (area light) or intensity (point, spot) a light vertex emits along `w`.
fn emitted(scene: &Scene, v: &PathVertex, w: Vec3) -> Vec3 {
    match v.node {
        Node::Surface => scene.emitted(v.sp.tri, v.sp.ng, v.sp.uv, w),
        Node::PointLight => match scene.lights.list[v.light as usize] {
            Light::Point { intensity, .. } => intensity,
            Light::Spot { frame, intensity, cos_inner, cos_outer, .. } => {
                intensity * crate::scene::emitter::spot_falloff(frame.n.dot(w), cos_inner, cos_outer)
            }
            _ => Vec3::ZERO,
        },
        Node::Lens => Vec3::ZERO,
    }
}

/// |cos| at a light vertex towards `w` (1 for point lights).
#[inline]
fn light_cos(v: &PathVertex, w: Vec3) -> f32 {
    if v.node == Node::Surface { v.sp.ng.dot(w).abs() } else { 1.0 }
}

/// Chooses a light ∝ power and a point on it (the first vertex of a light sub-path; its density
/// is `Scene::pdf_light_position`). Lights at infinity are not path vertices here.
pub fn sample_light_vertex(scene: &Scene, rng: &mut Pcg32) -> Option<PathVertex> {
    let choice = scene.lights.distribution.sample(rng.next_f32());
    let light = choice.index as u32;
    match scene.lights.list[choice.index] {
        Light::Area { tri, .. } => {
            let b = sample_uniform_triangle(Vec2::new(rng.next_f32(), rng.next_f32()));
            Some(PathVertex::surface(scene, scene.surface_point(tri, b.x, b.y)))
        }
        Light::Point { position, .. } | Light::Spot { position, .. } => {
            let sp = SurfacePoint { p: position, ng: Vec3::ZERO, ns: Vec3::ZERO, uv: Vec2::ZERO, tri: NO_TRI };
            Some(PathVertex { node: Node::PointLight, sp, light, kind: None })
        }
        Light::Sun(_) | Light::Sky(_) => None,
    }
}

/// A uniform raster position.
pub fn uniform_raster(scene: &Scene, rng: &mut Pcg32) -> Vec2 {
    let cam = &scene.camera;
    Vec2::new(rng.next_f32() * cam.width as f32, rng.next_f32() * cam.height as f32)
}

/// Traces from `from` along `dir`; the surface vertex hit, if any.
pub fn trace(scene: &Scene, accel: &Accel, from: &PathVertex, dir: Vec3, stats: &mut RayStats) -> Option<PathVertex> {
    stats.closest += 1;
    let hit = accel.intersect(from.origin_towards(scene, dir), dir, f32::INFINITY)?;
    Some(PathVertex::surface(scene, scene.surface_point(hit.tri, hit.b1, hit.b2)))
}

/// True when nothing blocks the segment between two vertices.
pub fn visible(scene: &Scene, accel: &Accel, a: &PathVertex, b: &PathVertex, stats: &mut RayStats) -> bool {
    let oa = a.origin_towards(scene, b.p() - a.p());
    let ob = b.origin_towards(scene, a.p() - b.p());
    stats.shadow += 1;
    !accel.occluded(oa, ob - oa, SHADOW_T_MAX)
}

/// Extends a walk (`walk`, in the order it was walked: the last vertex is the current one) by
/// `count` vertices, sampling each direction as its sub-path would: the light's emission, the
/// lens's uniform raster position, or the BSDF (in `mode`). No Russian roulette. False when the
/// walk misses or a sample fails.
pub fn extend(
    scene: &Scene,
    accel: &Accel,
    rng: &mut Pcg32,
    walk: &mut Vec<PathVertex>,
    count: usize,
    mode: TransportMode,
    stats: &mut RayStats,
) -> bool {
    for _ in 0..count {
        let n = walk.len();
        let cur = walk[n - 1];
        let dir = match cur.node {
            Node::Lens => scene.camera.ray_from_lens(cur.p(), uniform_raster(scene, rng)).dir,
            _ if n == 1 => {
                // The light vertex a light sub-path starts from.
                let u = Vec2::new(rng.next_f32(), rng.next_f32());
                match scene.sample_light_direction(cur.light, cur.sp.ng, u) {
                    Some((d, pdf, _)) if pdf > 0.0 => d,
                    _ => return false,
                }
            }
            _ => {
                let Some(wo) = (walk[n - 2].p() - cur.p()).try_normalize() else { return false };
                let Some(bsdf) = cur.bsdf(wo) else { return false };
                let u_lobe = rng.next_f32();
                let u = Vec2::new(rng.next_f32(), rng.next_f32());
                match bsdf.sample(wo, u_lobe, u, mode) {
                    Some(bs) => bs.wi,
                    None => return false,
                }
            }
        };
        let Some(v) = trace(scene, accel, &cur, dir, stats) else { return false };
        walk.push(v);
    }
    true
}

/// The scattering weight `f·|cos|/p` of a specular vertex for the pair (`wo`, `wi`) as sampled
/// from `wo` in `mode` (pbrt's convention of [`Bsdf::sample`]), or `None` when the pair is not a
/// specular pair. With `forced`, the lobe's probability is not divided out (a perturbation
/// follows the old path's event instead of choosing it).
fn specular_weight(bsdf: &Bsdf, wo: Vec3, wi: Vec3, mode: TransportMode, forced: bool) -> Option<Vec3> {
    let (lo, li) = (bsdf.frame.to_local(wo), bsdf.frame.to_local(wi));
    let close = |expected: Vec3| expected.dot(li) > 0.9999;
    let w = match bsdf.kind {
        BsdfKind::Mirror { reflectance } => {
            if !close(mirror::reflect(lo)) {
                return None;
            }
            reflectance
        }
        BsdfKind::Dielectric { eta, tint } => {
            let fr = dielectric::fresnel(lo.z, eta);
            if lo.z * li.z > 0.0 {
                if !close(mirror::reflect(lo)) || fr <= 0.0 {
                    return None;
                }
                if forced { tint * fr } else { tint }
            } else {
                let (t, eta_rel) = dielectric::refract(lo, eta)?;
                if !close(t) || fr >= 1.0 {
                    return None;
                }
                let mut w = if forced { tint * (1.0 - fr) } else { tint };
                if mode == TransportMode::Radiance {
                    w /= eta_rel * eta_rel;
                }
                w
            }
        }
        _ => return None,
    };
    Some(match mode {
        TransportMode::Radiance => w,
        TransportMode::Importance => w * shading_correction(bsdf, wo, wi),
    })
}

/// Which event a specular vertex's pair (`wo`, `wi`) is: true for reflection.
pub fn reflects(v: &PathVertex, wo: Vec3, wi: Vec3) -> bool {
    match v.bsdf(wo) {
        Some(b) => b.frame.to_local(wo).z * b.frame.to_local(wi).z > 0.0,
        None => true,
    }
}

/// How the perturbations evaluate a path: specular events forced (no lobe probability divided
/// out), and optionally one light-side vertex whose outgoing direction was perturbed (its
/// direction density, symmetric, is left out).
#[derive(Clone, Copy, Debug, Default)]
pub struct Forced {
    /// Specular events follow the old path.
    pub specular: bool,
    /// The light-side vertex whose direction was perturbed.
    pub perturbed: Option<usize>,
}

/// `C*_{s,t}` of every strategy of a path, and where it lands on the image.
#[derive(Clone, Debug, Default)]
pub struct Evaluation {
    /// `C*_{s, k−s}` for s = 0 … k (`None`: the strategy cannot produce the path).
    pub contrib: Vec<Option<DVec3>>,
    /// Raster position (None: off the image).
    pub raster: Option<Vec2>,
}

impl Evaluation {
    /// The path's colour with unit luminance, f / lum(f) (any valid strategy's C*, normalised;
    /// zero when the path contributes nothing).
    pub fn colour(&self) -> Vec3 {
        for c in self.contrib.iter().flatten() {
            let l = luminance(c.as_vec3()) as f64;
            if l > 0.0 && l.is_finite() {
                return (*c / l).as_vec3();
            }
        }
        Vec3::ZERO
    }

    /// lum(C*_s), or 0 for an invalid strategy.
    pub fn lum(&self, s: usize) -> f64 {
        match self.contrib.get(s).copied().flatten() {
            Some(c) => {
                let l = luminance(c.as_vec3()) as f64;
                if l.is_finite() && l > 0.0 { l } else { 0.0 }
            }
            None => 0.0,
        }
    }

    /// Σ over the strategies `range` of `weight(s) / lum(C*_s)`: path density over f_lum of a
    /// mixture of strategies (0 when none is valid).
    pub fn inverse_sum(&self, range: std::ops::RangeInclusive<usize>, weight: impl Fn(usize) -> f64) -> f64 {
        range
            .map(|s| {
                let l = self.lum(s);
                if l > 0.0 { weight(s) / l } else { 0.0 }
            })
            .sum()
    }
}

/// Evaluates every strategy of `path` (light → lens; see the module doc).
pub fn evaluate(scene: &Scene, path: &[PathVertex], forced: Forced) -> Evaluation {
    let k = path.len();
    let mut out = Evaluation { contrib: vec![None; k + 1], raster: None };
    if k < 2 || path[k - 1].node != Node::Lens || path[0].light == NO_LIGHT {
        return out;
    }
    let cam = &scene.camera;
    // Unit directions w[i] from y_i to y_{i+1}, and squared lengths.
    let mut w = Vec::with_capacity(k - 1);
    let mut d2 = Vec::with_capacity(k - 1);
    for i in 0..k - 1 {
        let d = path[i + 1].p() - path[i].p();
        let l2 = d.length_squared();
        if !(l2 > 0.0) || !l2.is_finite() {
            return out;
        }
        w.push(d / l2.sqrt());
        d2.push(l2);
    }
    let lens = path[k - 1].p();
    out.raster = cam.raster_of(lens, -w[k - 2]);
    if out.raster.is_none() {
        return out;
    }
    let y0 = &path[0];
    let p_pos = scene.pdf_light_position(y0.light) as f64;
    let (p_lens, _) = cam.pdf_we(-w[k - 2]);
    if !(p_pos > 0.0) || !(p_lens > 0.0) {
        return out;
    }
    let forced_spec = forced.specular;

    // Light sub-path factors lf[i]: y_i → y_{i+1} (importance transport).
    let light_factor = |i: usize| -> Option<DVec3> {
        let wi = w[i];
        let unit_pdf = forced.perturbed == Some(i);
        if i == 0 {
            let le = emitted(scene, y0, wi);
            let pdf = if unit_pdf { 1.0 } else { scene.pdf_light_direction(y0.light, y0.sp.ng, wi) };
            if !(pdf > 0.0) {
                return None;
            }
            return Some((le * (light_cos(y0, wi) / pdf)).as_dvec3());
        }
        let v = &path[i];
        let wo = -w[i - 1];
        let bsdf = v.bsdf(wo)?;
        if bsdf.is_delta() {
            return specular_weight(&bsdf, wo, wi, TransportMode::Importance, forced_spec).map(|x| x.as_dvec3());
        }
        let pdf = if unit_pdf { 1.0 } else { bsdf.pdf_w(wo, wi) };
        if !(pdf > 0.0) {
            return None;
        }
        let f = bsdf.f(wo, wi) * (bsdf.abs_cos(wi) * shading_correction(&bsdf, wo, wi) / pdf);
        Some(f.as_dvec3())
    };
    // Camera sub-path factors ef[i]: y_i → y_{i−1} (radiance transport).
    let eye_factor = |i: usize| -> Option<DVec3> {
        let wi = -w[i - 1];
        if i == k - 1 {
            let we = cam.we(lens, wi);
            let (_, pdf_dir) = cam.pdf_we(wi);
            if !(pdf_dir > 0.0) {
                return None;
            }
            return Some(DVec3::splat((we * wi.dot(cam.forward) / pdf_dir) as f64));
        }
        let v = &path[i];
        let wo = w[i];
        let bsdf = v.bsdf(wo)?;
        if bsdf.is_delta() {
            return specular_weight(&bsdf, wo, wi, TransportMode::Radiance, forced_spec).map(|x| x.as_dvec3());
        }
        let pdf = bsdf.pdf_w(wo, wi);
        if !(pdf > 0.0) {
            return None;
        }
        Some((bsdf.f(wo, wi) * (bsdf.abs_cos(wi) / pdf)).as_dvec3())
    };

    // alpha_l[s]: light sub-path of s vertices (s = 1 … k − 1); None once a factor is invalid.
    let mut alpha_l: Vec<Option<DVec3>> = vec![None; k];
    alpha_l[1] = Some(DVec3::splat(1.0 / p_pos));
    for s in 2..k {
        alpha_l[s] = alpha_l[s - 1].and_then(|a| light_factor(s - 2).map(|f| a * f));
    }
    // alpha_e[t]: camera sub-path of t vertices (t = 1 … k).
    let mut alpha_e: Vec<Option<DVec3>> = vec![None; k + 1];
    alpha_e[1] = Some(DVec3::splat(1.0 / p_lens as f64));
    for t in 2..=k {
        alpha_e[t] = alpha_e[t - 1].and_then(|a| eye_factor(k - t + 1).map(|f| a * f));
    }

    // s = 0: the camera sub-path reaches an area light.
    if y0.node == Node::Surface
        && let Some(a) = alpha_e[k]
    {
        out.contrib[0] = Some(a * emitted(scene, y0, w[0]).as_dvec3());
    }
    // 1 ≤ s ≤ k − 1: a deterministic connection y_{s−1} ↔ y_s.
    for s in 1..k {
        let (Some(al), Some(ae)) = (alpha_l[s], alpha_e[k - s]) else { continue };
        let (a, b) = (&path[s - 1], &path[s]);
        let wc = w[s - 1];
        let (fa, cos_a) = if s == 1 {
            (emitted(scene, a, wc), light_cos(a, wc))
        } else {
            if a.is_specular() {
                continue;
            }
            let wo = -w[s - 2];
            let Some(bsdf) = a.bsdf(wo) else { continue };
            (bsdf.f(wo, wc) * shading_correction(&bsdf, wo, wc), bsdf.abs_cos(wc))
        };
        let (fb, cos_b) = if s == k - 1 {
            (Vec3::splat(cam.we(lens, -wc)), (-wc).dot(cam.forward).max(0.0))
        } else {
            if b.is_specular() {
                continue;
            }
            let wo = w[s];
            let Some(bsdf) = b.bsdf(wo) else { continue };
            (bsdf.f(wo, -wc), bsdf.abs_cos(wc))
        };
        let c = (fa * fb).as_dvec3() * (cos_a as f64 * cos_b as f64 / d2[s - 1] as f64);
        out.contrib[s] = Some(al * c * ae);
    }
    out
}
