//! Perturbations: small moves that keep a path's length and its sequence of specular and
//! non-specular vertices (Veach 1997 §11.4.3; Cline & Egbert §3.4, docs/bibliography.md).
//!
//! - **Lens** (paths … (L|D) D S* E): move the raster position by an offset of radius between
//!   r₁ = 0.1 pixel and r₂ = 0.1 × image width, log-uniform (Cline & Egbert Appendix B), trace the
//!   same specular events from the same lens point to a new first non-specular vertex, and join it
//!   to the old one before it.
//! - **Caustic** (paths … (L|D) S+ D E): turn the direction leaving the last non-specular vertex
//!   before the specular chain by an angle between θ₁ = 10⁻⁴ and θ₂ = 0.1 radian, log-uniform,
//!   follow the same specular events to a new diffuse vertex, and join it to the lens.
//!
//! Both offsets have densities that depend only on the distance between old and new (symmetric),
//! so they cancel in T(ȳ|x̄) / T(x̄|ȳ). What remains is the density of the regenerated vertices
//! through the deterministic specular chain, which is the camera (lens) or light (caustic)
//! sub-path's density with the specular events' probabilities left out and, for the caustic
//! perturbation, without the perturbed vertex's direction density: so
//! `a = lum C*_s(ȳ) / lum C*_s(x̄)` evaluated with [`Forced`] (s = the kept light vertices).

use glam::{Vec2, Vec3};

use super::mutation::{Context, Mutation, Proposal, State, first_diffuse_from_lens, joins};
use super::path::{Forced, PathVertex, evaluate, reflects, trace, visible};
use crate::bsdf::{Bsdf, BsdfKind, Frame, dielectric, mirror};
use crate::sampling::Pcg32;
use crate::scene::Camera;
use crate::stats::RayStats;

/// A log-uniform radius in [r1, r2] (Cline & Egbert Appendix B/C).
fn log_uniform(r1: f32, r2: f32, u: f32) -> f32 {
    r2 * (-(r2 / r1).ln() * u).exp()
}

/// `raster` moved by an offset of radius between r₁ = 0.1 pixel and r₂ = 0.1 × image width,
/// log-uniform, in a uniform direction (a density that depends only on the offset's length);
/// None off the image.
fn perturbed_raster(cam: &Camera, raster: Vec2, rng: &mut Pcg32) -> Option<Vec2> {
    let (u1, u2) = (rng.next_f32(), rng.next_f32());
    let r = log_uniform(0.1, 0.1 * cam.width as f32, u1);
    let (sin, cos) = (std::f32::consts::TAU * u2).sin_cos();
    let p = raster + Vec2::new(r * cos, r * sin);
    (p.x >= 0.0 && p.y >= 0.0 && p.x < cam.width as f32 && p.y < cam.height as f32).then_some(p)
}

/// `w` turned by an angle between θ₁ = 10⁻⁴ and θ₂ = 0.1 radian, log-uniform, about a uniform
/// axis (Cline & Egbert Appendix C): a density in solid angle that depends only on the angle
/// between old and new, so the same from either side.
fn turn(w: Vec3, rng: &mut Pcg32) -> Vec3 {
    let (u1, u2) = (rng.next_f32(), rng.next_f32());
    let theta = log_uniform(1e-4, 0.1, u1);
    let phi = std::f32::consts::TAU * u2;
    let local = Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
    Frame::from_normal(w).to_world(local).normalize()
}

/// The direction leaving specular vertex `v` when it was entered from `wo` (pointing away from
/// it) and the event is a reflection (`reflect`) or a refraction; None if the event is
/// impossible there (total internal reflection, a mirror asked to refract).
fn follow(v: &PathVertex, wo: Vec3, reflect: bool) -> Option<Vec3> {
    let kind = v.kind?;
    let bsdf = Bsdf::new(kind, v.sp.ns, v.sp.ng, wo);
    let lo = bsdf.frame.to_local(wo);
    let li = match (kind, reflect) {
        (BsdfKind::Mirror { .. }, true) | (BsdfKind::Dielectric { .. }, true) => mirror::reflect(lo),
        (BsdfKind::Dielectric { eta, .. }, false) => dielectric::refract(lo, eta)?.0,
        _ => return None,
    };
    let wi = bsdf.frame.to_world(li);
    // The geometric side must agree with the event (as in `Bsdf::sample`).
    let same_shading = lo.z * li.z > 0.0;
    let same_geometric = wo.dot(bsdf.ng) * wi.dot(bsdf.ng) > 0.0;
    (same_shading == same_geometric).then_some(wi)
}

/// Traces the specular chain of `old` from vertex `from` (exclusive, stepping by `step` = ±1)
/// to vertex `to` (inclusive) along the new direction `dir`, repeating the old events, into
/// `out`. The vertex at `to` must be non-specular (it ends the chain).
#[allow(clippy::too_many_arguments)]
fn retrace(
    cx: &Context,
    old: &[PathVertex],
    start: &PathVertex,
    mut dir: Vec3,
    (from, to, step): (usize, usize, isize),
    out: &mut Vec<PathVertex>,
    stats: &mut RayStats,
) -> Option<()> {
    let mut cur = *start;
    let mut i = from as isize;
    loop {
        i += step;
        let v = trace(cx.scene, cx.accel, &cur, dir, stats)?;
        let oi = i as usize;
        if oi == to {
            if v.is_specular() {
                return None;
            }
            out.push(v);
            return Some(());
        }
        if !v.is_specular() {
            return None;
        }
        // The old event at this vertex: entered from old[oi − step], left towards old[oi + step].
        let o = &old[oi];
        let w_in = (old[(i - step) as usize].p() - o.p()).normalize();
        let w_out = (old[(i + step) as usize].p() - o.p()).normalize();
        let reflect = reflects(o, w_in, w_out);
        dir = follow(&v, -dir, reflect)?;
        out.push(v);
        cur = v;
    }
}

/// The lens perturbation.
pub struct LensPerturbation;

impl Mutation for LensPerturbation {
    fn name(&self) -> &'static str {
        "lens"
    }

    /// Paths … (L|D) D S* E.
    fn applies(&self, x: &State) -> bool {
        let a = first_diffuse_from_lens(&x.path);
        !(x.path[a].is_specular() || (a >= 2 && x.path[a - 1].is_specular()))
    }

    fn propose(&self, cx: &Context, x: &State, rng: &mut Pcg32, stats: &mut RayStats) -> Option<Proposal> {
        let scene = cx.scene;
        let cam = &scene.camera;
        let xp = &x.path;
        let k = xp.len();
        if !self.applies(x) {
            return None;
        }
        // a: the first non-specular vertex seen from the lens; the light side keeps 0 … a − 1.
        let a = first_diffuse_from_lens(xp);
        let raster = perturbed_raster(cam, x.raster(), rng)?;
        let lens = xp[k - 1];
        let dir = cam.ray_from_lens(lens.p(), raster).dir;
        let mut new = Vec::with_capacity(k - a);
        retrace(cx, xp, &lens, dir, (k - 1, a, -1), &mut new, stats)?;
        let mut path: Vec<PathVertex> = xp[..a].to_vec();
        path.extend(new.iter().rev());
        path.push(lens);
        // When a = 0 (L S* E) the new chain must end on a light.
        if !joins(cx, &path, a, stats) {
            return None;
        }
        let forced = Forced { specular: true, ..Default::default() };
        let new_l = evaluate(scene, &path, forced).lum(a);
        let old_l = evaluate(scene, xp, forced).lum(a);
        Some(Proposal::with_ratio(State::new(scene, path)?, new_l, old_l))
    }
}

/// The caustic perturbation.
pub struct CausticPerturbation;

/// The vertex x_j of a path … x_j (L|D) S+ x_{k−2} (D) E whose direction the caustic
/// perturbation turns.
fn caustic_start(xp: &[PathVertex]) -> Option<usize> {
    let k = xp.len();
    if k < 4 || xp[k - 2].is_specular() || !xp[k - 3].is_specular() {
        return None;
    }
    let mut j = k - 3;
    while j > 0 && xp[j].is_specular() {
        j -= 1;
    }
    (!xp[j].is_specular()).then_some(j)
}

/// Whether a path is … (L|D) D S+ x_a (D) S* E with x_a the first non-specular vertex from
/// the lens (a ≥ 2), at most 128 vertices long: the multi-chain perturbation's paths.
fn multi_chain_start(xp: &[PathVertex]) -> Option<usize> {
    let a = first_diffuse_from_lens(xp);
    (a >= 2 && !xp[a].is_specular() && xp[a - 1].is_specular() && xp.len() <= 128).then_some(a)
}

impl Mutation for CausticPerturbation {
    fn name(&self) -> &'static str {
        "caustic"
    }

    fn applies(&self, x: &State) -> bool {
        caustic_start(&x.path).is_some()
    }

    fn propose(&self, cx: &Context, x: &State, rng: &mut Pcg32, stats: &mut RayStats) -> Option<Proposal> {
        let scene = cx.scene;
        let xp = &x.path;
        let k = xp.len();
        let j = caustic_start(xp)?;
        let dir = turn((xp[j + 1].p() - xp[j].p()).normalize(), rng);
        let mut new = Vec::with_capacity(k - j);
        retrace(cx, xp, &xp[j], dir, (j, k - 2, 1), &mut new, stats)?;
        let mut path: Vec<PathVertex> = xp[..=j].to_vec();
        path.extend(new);
        path.push(xp[k - 1]);
        if !visible(scene, cx.accel, &path[k - 2], &path[k - 1], stats) {
            return None;
        }
        let forced = Forced { specular: true, perturbed: Some(j), ..Default::default() };
        let new_l = evaluate(scene, &path, forced).lum(k - 1);
        let old_l = evaluate(scene, xp, forced).lum(k - 1);
        Some(Proposal::with_ratio(State::new(scene, path)?, new_l, old_l))
    }
}

/// The multi-chain perturbation.
pub struct MultiChainPerturbation;

impl Mutation for MultiChainPerturbation {
    fn name(&self) -> &'static str {
        "multichain"
    }

    fn applies(&self, x: &State) -> bool {
        multi_chain_start(&x.path).is_some()
    }

    fn propose(&self, cx: &Context, x: &State, rng: &mut Pcg32, stats: &mut RayStats) -> Option<Proposal> {
        let scene = cx.scene;
        let cam = &scene.camera;
        let xp = &x.path;
        let k = xp.len();
        // … (L|D) D S+ x_a (D) S* E: a, the first non-specular vertex seen from the lens, sees a
        // specular chain towards the light (else the lens perturbation covers the path).
        let a = multi_chain_start(xp)?;
        let raster = perturbed_raster(cam, x.raster(), rng)?;
        let lens = xp[k - 1];
        // The new vertices from y_{k−2} down, in that order.
        let mut new = Vec::with_capacity(k - 1);
        retrace(cx, xp, &lens, cam.ray_from_lens(lens.p(), raster).dir, (k - 1, a, -1), &mut new, stats)?;
        let mut forced = Forced { specular: true, ..Default::default() };
        // Each non-specular vertex c that sees a specular chain towards the light: turn the old
        // direction, follow the chain's events to the next non-specular vertex b, and stop once
        // b can be joined to the old x_{b−1} (or is the light).
        let mut c = a;
        let s = loop {
            forced.perturbed_eye |= 1u128 << c;
            let mut b = c - 1;
            while b > 0 && xp[b].is_specular() {
                b -= 1;
            }
            if xp[b].is_specular() {
                return None;
            }
            let from = *new.last().expect("the chain so far");
            let dir = turn((xp[c - 1].p() - xp[c].p()).normalize(), rng);
            retrace(cx, xp, &from, dir, (c, b, -1), &mut new, stats)?;
            if b == 0 || !xp[b - 1].is_specular() {
                break b;
            }
            c = b;
        };
        let mut path: Vec<PathVertex> = xp[..s].to_vec();
        path.extend(new.iter().rev());
        path.push(lens);
        if !joins(cx, &path, s, stats) {
            return None;
        }
        let new_l = evaluate(scene, &path, forced).lum(s);
        let old_l = evaluate(scene, xp, forced).lum(s);
        Some(Proposal::with_ratio(State::new(scene, path)?, new_l, old_l))
    }
}
