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
/// out), and optionally one light-side vertex and any camera-side vertices whose outgoing
/// direction was perturbed (their direction density, symmetric, is left out).
#[derive(Clone, Copy, Debug, Default)]
pub struct Forced {
    /// Specular events follow the old path.
    pub specular: bool,
    /// The light-side vertex whose direction was perturbed (towards the lens).
    pub perturbed: Option<usize>,
    /// Bit i: the camera-side vertex y_i's direction towards the light was perturbed (i < 128).
    pub perturbed_eye: u128,
}

impl Forced {
    /// Whether y_i's direction towards the light was perturbed.
    #[inline]
    pub fn eye_perturbed(&self, i: usize) -> bool {
        i < 128 && self.perturbed_eye >> i & 1 == 1
    }
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

/// The light sub-path's factor at a vertex `v` leaving along `wi` (importance transport):
/// emission over its direction density when `wo` is `None` (v is the light vertex y_0), else
/// the BSDF's `f·|cos|/p` with the shading-normal correction. `unit_pdf`: the direction
/// density is left out (a perturbed direction, [`Forced::perturbed`]).
fn light_factor(
    scene: &Scene,
    v: &PathVertex,
    wo: Option<Vec3>,
    wi: Vec3,
    forced_spec: bool,
    unit_pdf: bool,
) -> Option<DVec3> {
    let Some(wo) = wo else {
        let le = emitted(scene, v, wi);
        let pdf = if unit_pdf { 1.0 } else { scene.pdf_light_direction(v.light, v.sp.ng, wi) };
        if !(pdf > 0.0) {
            return None;
        }
        return Some((le * (light_cos(v, wi) / pdf)).as_dvec3());
    };
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
}

/// The camera sub-path's factor at a vertex `v` leaving along `wi` towards the light end
/// (radiance transport): the lens's `We·cos/p` when `wo` is `None` (v is the lens), else the
/// BSDF's `f·|cos|/p`. `unit_pdf`: the direction density is left out (a perturbed direction,
/// [`Forced::perturbed_eye`]).
fn eye_factor(
    scene: &Scene,
    v: &PathVertex,
    wo: Option<Vec3>,
    wi: Vec3,
    forced_spec: bool,
    unit_pdf: bool,
) -> Option<DVec3> {
    let cam = &scene.camera;
    let Some(wo) = wo else {
        let we = cam.we(v.p(), wi);
        let (_, pdf_dir) = cam.pdf_we(wi);
        if !(pdf_dir > 0.0) {
            return None;
        }
        return Some(DVec3::splat((we * wi.dot(cam.forward) / pdf_dir) as f64));
    };
    let bsdf = v.bsdf(wo)?;
    if bsdf.is_delta() {
        return specular_weight(&bsdf, wo, wi, TransportMode::Radiance, forced_spec).map(|x| x.as_dvec3());
    }
    let pdf = if unit_pdf { 1.0 } else { bsdf.pdf_w(wo, wi) };
    if !(pdf > 0.0) {
        return None;
    }
    Some((bsdf.f(wo, wi) * (bsdf.abs_cos(wi) / pdf)).as_dvec3())
}

/// The deterministic connection `c` of a vertex `a` (light side; `a_wo` towards its previous
/// vertex, `None` when a is the light vertex y_0) with `b` (camera side; `b_wo` towards its
/// next vertex, `None` when b is the lens) along the unit `wc` from a to b at squared distance
/// `d2`. `None` at a specular vertex (no strategy connects there).
fn connection(
    scene: &Scene,
    (a, a_wo): (&PathVertex, Option<Vec3>),
    (b, b_wo): (&PathVertex, Option<Vec3>),
    wc: Vec3,
    d2: f32,
) -> Option<DVec3> {
    let cam = &scene.camera;
    let (fa, cos_a) = match a_wo {
        None => (emitted(scene, a, wc), light_cos(a, wc)),
        Some(wo) => {
            if a.is_specular() {
                return None;
            }
            let bsdf = a.bsdf(wo)?;
            (bsdf.f(wo, wc) * shading_correction(&bsdf, wo, wc), bsdf.abs_cos(wc))
        }
    };
    let (fb, cos_b) = match b_wo {
        None => (Vec3::splat(cam.we(b.p(), -wc)), (-wc).dot(cam.forward).max(0.0)),
        Some(wo) => {
            if b.is_specular() {
                return None;
            }
            let bsdf = b.bsdf(wo)?;
            (bsdf.f(wo, -wc), bsdf.abs_cos(wc))
        }
    };
    Some((fa * fb).as_dvec3() * (cos_a as f64 * cos_b as f64 / d2 as f64))
}

/// Unit direction and squared length from `a` to `b` (`None` when degenerate).
#[inline]
fn direction(a: Vec3, b: Vec3) -> Option<(Vec3, f32)> {
    let d = b - a;
    let l2 = d.length_squared();
    (l2 > 0.0 && l2.is_finite()).then(|| (d / l2.sqrt(), l2))
}

/// Evaluates every strategy of `path` (light → lens; see the module doc).
pub fn evaluate(scene: &Scene, path: &[PathVertex], forced: Forced) -> Evaluation {
    let k = path.len();
    let mut out = Evaluation { contrib: vec![None; k + 1], raster: None };
    if k < 2 || path[k - 1].node != Node::Lens || path[0].light == NO_LIGHT {
        return out;
    }
    // Unit directions w[i] from y_i to y_{i+1}, and squared lengths.
    let mut w = Vec::with_capacity(k - 1);
    let mut d2 = Vec::with_capacity(k - 1);
    for i in 0..k - 1 {
        let Some((wi, l2)) = direction(path[i].p(), path[i + 1].p()) else { return out };
        w.push(wi);
        d2.push(l2);
    }
    let f = forced.specular;
    let light =
        |i: usize| light_factor(scene, &path[i], (i > 0).then(|| -w[i - 1]), w[i], f, forced.perturbed == Some(i));
    let eye = |i: usize| eye_factor(scene, &path[i], (i < k - 1).then(|| w[i]), -w[i - 1], f, forced.eye_perturbed(i));
    let link = |s: usize| {
        let a = (&path[s - 1], (s > 1).then(|| -w[s - 2]));
        let b = (&path[s], (s < k - 1).then(|| w[s]));
        connection(scene, a, b, w[s - 1], d2[s - 1])
    };
    let raster = scene.camera.raster_of(path[k - 1].p(), -w[k - 2]);
    assemble(scene, &path[0], raster, -w[k - 2], w[0], (light, eye, link), &mut out);
    out
}

/// Fills `out` for a path of `out.contrib.len() − 1` vertices from its factors: `light(i)`,
/// `eye(i)` and `link(s)` are the light factor and the camera factor at y_i and the connection
/// of y_{s−1} with y_s (as [`evaluate`] defines them); `y0` the light vertex, `raster` where the
/// lens sees y_{k−2}, `to_scene` the direction from the lens to y_{k−2}, `w0` from y_0 to y_1.
fn assemble(
    scene: &Scene,
    y0: &PathVertex,
    raster: Option<Vec2>,
    to_scene: Vec3,
    w0: Vec3,
    (light, eye, link): (
        impl Fn(usize) -> Option<DVec3>,
        impl Fn(usize) -> Option<DVec3>,
        impl Fn(usize) -> Option<DVec3>,
    ),
    out: &mut Evaluation,
) {
    let k = out.contrib.len() - 1;
    let cam = &scene.camera;
    out.raster = raster;
    if out.raster.is_none() {
        return;
    }
    let p_pos = scene.pdf_light_position(y0.light) as f64;
    let (p_lens, _) = cam.pdf_we(to_scene);
    if !(p_pos > 0.0) || !(p_lens > 0.0) {
        return;
    }
    // alpha_l[s]: light sub-path of s vertices (s = 1 … k − 1); None once a factor is invalid.
    let mut alpha_l: [Option<DVec3>; MAX_ASSEMBLED] = [None; MAX_ASSEMBLED];
    let mut alpha_l_vec;
    let alpha_l: &mut [Option<DVec3>] = if k <= MAX_ASSEMBLED {
        &mut alpha_l[..k]
    } else {
        alpha_l_vec = vec![None; k];
        &mut alpha_l_vec
    };
    alpha_l[1] = Some(DVec3::splat(1.0 / p_pos));
    for s in 2..k {
        alpha_l[s] = alpha_l[s - 1].and_then(|a| light(s - 2).map(|f| a * f));
    }
    // alpha_e[t]: camera sub-path of t vertices (t = 1 … k), folded into the loop below from
    // t = k − 1 down (s = 1 up), after s = 0 took alpha_e[k].
    let mut alpha_e: [Option<DVec3>; MAX_ASSEMBLED + 1] = [None; MAX_ASSEMBLED + 1];
    let mut alpha_e_vec;
    let alpha_e: &mut [Option<DVec3>] = if k <= MAX_ASSEMBLED {
        &mut alpha_e[..k + 1]
    } else {
        alpha_e_vec = vec![None; k + 1];
        &mut alpha_e_vec
    };
    alpha_e[1] = Some(DVec3::splat(1.0 / p_lens as f64));
    for t in 2..=k {
        alpha_e[t] = alpha_e[t - 1].and_then(|a| eye(k - t + 1).map(|f| a * f));
    }

    // s = 0: the camera sub-path reaches an area light.
    if y0.node == Node::Surface
        && let Some(a) = alpha_e[k]
    {
        out.contrib[0] = Some(a * emitted(scene, y0, w0).as_dvec3());
    }
    // 1 ≤ s ≤ k − 1: a deterministic connection y_{s−1} ↔ y_s.
    for s in 1..k {
        let (Some(al), Some(ae)) = (alpha_l[s], alpha_e[k - s]) else { continue };
        let Some(c) = link(s) else { continue };
        out.contrib[s] = Some(al * c * ae);
    }
}

/// Paths up to this many vertices are assembled without a heap allocation.
const MAX_ASSEMBLED: usize = 32;

/// The strategies of every connection of a light walk with a camera walk (the paths
/// `light[..s]` followed by `eye[..t]` reversed, as the bootstrap forms them), evaluated as
/// [`evaluate`] would, with every factor that depends on one walk alone computed once: a
/// candidate then costs the handful of factors next to its connection instead of all 3k.
pub struct WalkPair<'a> {
    light: &'a [PathVertex],
    eye: &'a [PathVertex],
    /// Light walk: direction and squared length light[i] → light[i+1].
    wl: Vec<Option<(Vec3, f32)>>,
    /// Camera walk: direction and squared length eye[m] → eye[m−1] (index 0 unused).
    we: Vec<Option<(Vec3, f32)>>,
    /// At light[i] inside the light walk (i ≤ len − 2): light factor, camera factor (i ≥ 1),
    /// connection of light[i−1] with light[i] (i ≥ 1).
    l_light: Vec<Option<DVec3>>,
    l_eye: Vec<Option<DVec3>>,
    l_link: Vec<Option<DVec3>>,
    /// At eye[m] inside the camera walk: light factor (1 ≤ m ≤ len − 2), camera factor
    /// (m ≤ len − 2), connection of eye[m] with eye[m−1] (1 ≤ m ≤ len − 2), and the same two
    /// with eye[m] as the light vertex y_0 (an emitter the camera walk hit; m ≥ 1).
    e_light: Vec<Option<DVec3>>,
    e_eye: Vec<Option<DVec3>>,
    e_link: Vec<Option<DVec3>>,
    e0_light: Vec<Option<DVec3>>,
    e0_link: Vec<Option<DVec3>>,
    /// α^L of light[..s] (s ≥ 1) and α^E of eye[..t] (t ≥ 2), as [`assemble`] forms them.
    alpha_l: Vec<Option<DVec3>>,
    alpha_e: Vec<Option<DVec3>>,
    /// Where the lens sees eye[1].
    raster: Option<Vec2>,
}

/// The connection of a candidate (s ≥ 1): direction and squared distance light[s−1] → eye[t−1].
type Link = Option<(Vec3, f32)>;

impl<'a> WalkPair<'a> {
    /// Precomputes the walks' own factors (`eye[0]` is the lens).
    pub fn new(scene: &Scene, light: &'a [PathVertex], eye: &'a [PathVertex]) -> Self {
        let (nl, ne) = (light.len(), eye.len());
        let wl: Vec<_> = (0..nl.saturating_sub(1)).map(|i| direction(light[i].p(), light[i + 1].p())).collect();
        let we: Vec<_> = (0..ne).map(|m| if m == 0 { None } else { direction(eye[m].p(), eye[m - 1].p()) }).collect();
        let dir_l = |i: usize| wl.get(i).copied().flatten().map(|x| x.0);
        let dir_e = |m: usize| we.get(m).copied().flatten().map(|x| x.0);
        let mut pair = WalkPair {
            light,
            eye,
            l_light: vec![None; nl],
            l_eye: vec![None; nl],
            l_link: vec![None; nl],
            e_light: vec![None; ne],
            e_eye: vec![None; ne],
            e_link: vec![None; ne],
            e0_light: vec![None; ne],
            e0_link: vec![None; ne],
            alpha_l: vec![None; nl + 1],
            alpha_e: vec![None; ne + 1],
            raster: None,
            wl: Vec::new(),
            we: Vec::new(),
        };
        for i in 0..nl.saturating_sub(1) {
            let Some(wi) = dir_l(i) else { break };
            let wo = if i == 0 { None } else { Some(-dir_l(i - 1).expect("checked at i − 1")) };
            pair.l_light[i] = light_factor(scene, &light[i], wo, wi, false, false);
            if let Some(wo) = wo {
                pair.l_eye[i] = eye_factor(scene, &light[i], Some(wi), wo, false, false);
                let (_, d2) = wl[i - 1].expect("checked at i − 1");
                let a_wo = if i == 1 { None } else { Some(-dir_l(i - 2).expect("checked")) };
                pair.l_link[i] = connection(scene, (&light[i - 1], a_wo), (&light[i], Some(wi)), -wo, d2);
            }
        }
        for m in 0..ne.saturating_sub(1) {
            // eye[m] between eye[m − 1] (towards the lens) and eye[m + 1].
            let Some(back) = dir_e(m + 1).map(|d| -d) else { continue };
            let towards_lens = if m == 0 { None } else { dir_e(m) };
            if m > 0 && towards_lens.is_none() {
                continue;
            }
            pair.e_eye[m] = eye_factor(scene, &eye[m], towards_lens, back, false, false);
            if let Some(wl_) = towards_lens {
                pair.e_light[m] = light_factor(scene, &eye[m], Some(back), wl_, false, false);
                let (_, d2) = we[m].expect("checked");
                let b_wo = if m == 1 { None } else { dir_e(m - 1) };
                if m == 1 || b_wo.is_some() {
                    pair.e_link[m] = connection(scene, (&eye[m], Some(back)), (&eye[m - 1], b_wo), wl_, d2);
                }
            }
        }
        for m in 1..ne {
            if eye[m].light == NO_LIGHT {
                continue;
            }
            let Some((wl_, d2)) = we[m] else { continue };
            pair.e0_light[m] = light_factor(scene, &eye[m], None, wl_, false, false);
            let b_wo = if m == 1 { None } else { dir_e(m - 1) };
            if m == 1 || b_wo.is_some() {
                pair.e0_link[m] = connection(scene, (&eye[m], None), (&eye[m - 1], b_wo), wl_, d2);
            }
        }
        let cam = &scene.camera;
        if nl >= 1 {
            let p_pos = scene.pdf_light_position(light[0].light) as f64;
            if p_pos > 0.0 {
                pair.alpha_l[1] = Some(DVec3::splat(1.0 / p_pos));
                for s in 2..=nl {
                    pair.alpha_l[s] = pair.alpha_l[s - 1].and_then(|a| pair.l_light[s - 2].map(|f| a * f));
                }
            }
        }
        if let Some(to_scene) = dir_e(1).map(|d| -d) {
            pair.raster = cam.raster_of(eye[0].p(), to_scene);
            let (p_lens, _) = cam.pdf_we(to_scene);
            if p_lens > 0.0 {
                pair.alpha_e[1] = Some(DVec3::splat(1.0 / p_lens as f64));
                for t in 2..=ne {
                    pair.alpha_e[t] = pair.alpha_e[t - 1].and_then(|a| pair.e_eye[t - 2].map(|f| a * f));
                }
            }
        }
        pair.wl = wl;
        pair.we = we;
        pair
    }

    /// Whether the path `light[..s]` + `eye[..t]` reversed exists (every direction
    /// non-degenerate, a light at its start), and its connection.
    fn link(&self, s: usize, t: usize) -> Option<Link> {
        let (light, eye) = (self.light, self.eye);
        let k = s + t;
        if k < 2 || t == 0 || s > light.len() || t > eye.len() {
            return None;
        }
        let y0 = if s > 0 { &light[0] } else { &eye[t - 1] };
        if y0.light == NO_LIGHT {
            return None;
        }
        let walk_ok = |n: usize, dirs: &[Option<(Vec3, f32)>], from: usize| (from..n).all(|i| dirs[i].is_some());
        if (s >= 2 && !walk_ok(s - 1, &self.wl, 0)) || (t >= 2 && !walk_ok(t, &self.we, 1)) {
            return None;
        }
        if s == 0 {
            return Some(None);
        }
        direction(light[s - 1].p(), eye[t - 1].p()).map(Some)
    }

    /// `C*_{s,t}` of the path `light[..s]` + `eye[..t]` reversed, the strategy that made it,
    /// with its raster position: `evaluate(..).contrib[s]` and `.raster`, from the cached
    /// prefixes and one connection, to decide whether a candidate needs its shadow ray and
    /// its other strategies.
    pub fn contribution(&self, scene: &Scene, s: usize, t: usize) -> Option<(DVec3, Vec2)> {
        let conn = self.link(s, t)?;
        let (light, eye) = (self.light, self.eye);
        let cam = &scene.camera;
        let (raster, ae) = if t >= 2 {
            (self.raster?, self.alpha_e[t]?)
        } else {
            let to_scene = -conn?.0;
            let raster = cam.raster_of(eye[0].p(), to_scene)?;
            let (p_lens, _) = cam.pdf_we(to_scene);
            if !(p_lens > 0.0) {
                return None;
            }
            (raster, DVec3::splat(1.0 / p_lens as f64))
        };
        if s == 0 {
            let y0 = &eye[t - 1];
            if y0.node != Node::Surface || !(scene.pdf_light_position(y0.light) > 0.0) {
                return None;
            }
            let w0 = self.we[t - 1]?.0;
            return Some((ae * emitted(scene, y0, w0).as_dvec3(), raster));
        }
        let al = self.alpha_l[s]?;
        let (wc, d2) = conn?;
        let a_wo = (s > 1).then(|| -self.wl[s - 2].expect("checked").0);
        let b_wo = (t > 1).then(|| self.we[t - 1].expect("checked").0);
        let c = connection(scene, (&light[s - 1], a_wo), (&eye[t - 1], b_wo), wc, d2)?;
        Some((al * c * ae, raster))
    }

    /// Every strategy of the path `light[..s]` + `eye[..t]` reversed, into `out` (as
    /// [`evaluate`] of that path with no forced events).
    pub fn evaluate(&self, scene: &Scene, s: usize, t: usize, out: &mut Evaluation) {
        let k = s + t;
        out.contrib.clear();
        out.contrib.resize(k + 1, None);
        out.raster = None;
        let (light, eye) = (self.light, self.eye);
        let Some(conn) = self.link(s, t) else { return };
        let y = |i: usize| if i < s { &light[i] } else { &eye[k - 1 - i] };
        // w[i]: direction y_i → y_{i+1}; d2 likewise.
        let wd = |i: usize| -> (Vec3, f32) {
            if i + 1 < s {
                self.wl[i].expect("checked")
            } else if i + 1 == s {
                conn.expect("s ≥ 1")
            } else {
                self.we[k - 1 - i].expect("checked")
            }
        };
        let w = |i: usize| wd(i).0;
        let light_f = |i: usize| -> Option<DVec3> {
            if i + 1 < s {
                self.l_light[i]
            } else if i > s {
                self.e_light[k - 1 - i]
            } else if s == 0 {
                self.e0_light[t - 1]
            } else {
                light_factor(scene, y(i), (i > 0).then(|| -w(i - 1)), w(i), false, false)
            }
        };
        let eye_f = |i: usize| -> Option<DVec3> {
            if i > s {
                self.e_eye[k - 1 - i]
            } else if i + 1 < s {
                self.l_eye[i]
            } else {
                eye_factor(scene, y(i), (i < k - 1).then(|| w(i)), -w(i - 1), false, false)
            }
        };
        let link = |j: usize| -> Option<DVec3> {
            if j + 1 < s {
                self.l_link[j]
            } else if j > s + 1 {
                self.e_link[k - j]
            } else if j == 1 && s == 0 {
                self.e0_link[t - 1]
            } else {
                let a = (y(j - 1), (j > 1).then(|| -w(j - 2)));
                let b = (y(j), (j < k - 1).then(|| w(j)));
                connection(scene, a, b, w(j - 1), wd(j - 1).1)
            }
        };
        let raster = if t >= 2 { self.raster } else { scene.camera.raster_of(eye[0].p(), -w(k - 2)) };
        assemble(scene, y(0), raster, -w(k - 2), w(0), (light_f, eye_f, link), out);
    }
}
