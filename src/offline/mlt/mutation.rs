//! The chain's state and the mutation interface, and the bidirectional mutation (Veach 1997
//! §11.4.2; Fischer §3.5.3 and Appendix B, docs/bibliography.md).
//!
//! Every mutation proposes ȳ from x̄ and returns the Metropolis–Hastings acceptance probability
//! `a = min(1, f(ȳ) T(x̄|ȳ) / (f(x̄) T(ȳ|x̄)))` (the target is the luminance of f). Mutations
//! write it as `Q(x̄|ȳ) / Q(ȳ|x̄)` with `Q(ȳ|x̄) = T(ȳ|x̄) / f(ȳ)`, which are sums of
//! `1 / lum(C*_{s,t})` ([`super::path::Evaluation`]): the densities of the vertices a mutation
//! keeps are the same in both directions and cancel.

use glam::{Vec2, Vec3};

use super::path::{Evaluation, Forced, Node, PathVertex, evaluate, extend, sample_light_vertex, visible};
use crate::accel::Accel;
use crate::bsdf::TransportMode;
use crate::sampling::Pcg32;
use crate::scene::Scene;
use crate::stats::RayStats;

/// A chain's state: a complete path, its strategies' contributions, and where it lands.
#[derive(Clone, Debug)]
pub struct State {
    /// y_0 (light) … y_{k−1} (lens).
    pub path: Vec<PathVertex>,
    /// Every strategy's C*.
    pub eval: Evaluation,
}

impl State {
    /// Evaluates `path`; None when it contributes nothing (or lands off the image).
    pub fn new(scene: &Scene, path: Vec<PathVertex>) -> Option<State> {
        let eval = evaluate(scene, &path, Forced::default());
        eval.raster?;
        if eval.colour() == Vec3::ZERO {
            return None;
        }
        Some(State { path, eval })
    }

    /// Raster position.
    pub fn raster(&self) -> Vec2 {
        self.eval.raster.unwrap_or(Vec2::ZERO)
    }
}

/// What a mutation proposes: the new state and the probability of accepting it.
pub struct Proposal {
    /// ȳ.
    pub state: State,
    /// a(ȳ|x̄) ∈ [0, 1].
    pub accept: f64,
}

impl Proposal {
    /// ȳ with `a = min(1, new / old)`: 1 when x̄'s own value is zero (any move away from a state
    /// the target gives no weight is accepted), 0 when the ratio is not finite.
    pub fn with_ratio(state: State, new: f64, old: f64) -> Proposal {
        let accept = if old > 0.0 { (new / old).min(1.0) } else { 1.0 };
        Proposal { state, accept: if accept.is_finite() { accept } else { 0.0 } }
    }
}

/// Whether the light side `path[..s]` and the regenerated camera side `path[s..]` of a proposed
/// path join: y_{s−1} sees y_s, or, when s = 0, the camera side ends on an emitting surface.
pub fn joins(cx: &Context, path: &[PathVertex], s: usize, stats: &mut RayStats) -> bool {
    if s == 0 {
        path[0].light != crate::scene::NO_LIGHT && path[0].node == Node::Surface
    } else {
        visible(cx.scene, cx.accel, &path[s - 1], &path[s], stats)
    }
}

/// What a proposal needs besides the state.
pub struct Context<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Its acceleration structure.
    pub accel: &'a Accel,
    /// Longest path, in vertices (scattering events + 2).
    pub max_vertices: usize,
}

/// One kind of mutation.
pub trait Mutation: Sync {
    /// Name for flags and statistics.
    fn name(&self) -> &'static str;
    /// Proposes a new state from `x` with its acceptance probability; `None` when the mutation
    /// does not apply to `x` or its sample failed (a miss, an occluded connection, zero f): the
    /// chain then keeps `x`, as for a rejection.
    fn propose(&self, cx: &Context, x: &State, rng: &mut Pcg32, stats: &mut RayStats) -> Option<Proposal>;
    /// Whether the mutation can propose from `x`. For a perturbation (every type but the
    /// bidirectional mutation) this depends only on the path's length and which of its vertices
    /// are specular, which its proposals keep: so the share a perturbation gets among those that
    /// apply ([`super::MltSettings::choose`]) is the same at x̄ and at every ȳ it proposes, and
    /// each type keeps detailed balance on its own.
    fn applies(&self, x: &State) -> bool;
}

/// The first non-specular vertex of `path` seen from the lens (0 when every vertex between is
/// specular).
pub fn first_diffuse_from_lens(path: &[PathVertex]) -> usize {
    let mut a = path.len() - 2;
    while a > 0 && path[a].is_specular() {
        a -= 1;
    }
    a
}

/// The bidirectional mutation: delete the sub-path x_{l+1} … x_{m−1} (kd vertices), add ka new
/// vertices, s′ of them by a light walk from x_l and t′ = ka − s′ by a camera walk from x_m, and
/// join the two ends with a shadow ray (Veach 1997 §11.4.2).
///
/// Deletion length: kd = 0, 1 with weights 0.25, 0.5, then 2^−(kd+1), normalised over the lengths
/// that have a position; the position uniform among the admissible ones. The lens is never kept
/// on the light side, and a point light (or the eye of a pinhole camera) is never kept as the end
/// next to the gap: it is deleted and sampled
/// again, so that one proposal cannot arise from two positions. Added length: ka = kd with weight
/// 0.5, kd ± 1 with 0.2 each, kd ± j with 0.2·2^−j, normalised over the lengths the path can
/// have; s′ uniform in 0 … ka. The proposal density sums over every split of the added vertices
/// that gives the same path (Fischer Appendix B).
pub struct Bidirectional;

/// True when x_l | gap | x_m is an admissible cut of a path of `n` vertices (`l = −1`: the
/// light vertex is deleted, `m = n`: the lens vertex is).
fn admissible(path: &[PathVertex], pinhole: bool, l: isize, m: usize) -> bool {
    let n = path.len();
    // The lens kept on the light side (l = n − 1) would be an interior vertex: never a path.
    let keeps_lens_inside = l + 1 == n as isize;
    let keeps_point_light = l == 0 && path[0].node == Node::PointLight;
    let keeps_pinhole = m + 1 == n && pinhole;
    !keeps_lens_inside && !keeps_point_light && !keeps_pinhole
}

/// Admissible positions l for deleting `kd` vertices.
fn positions(path: &[PathVertex], pinhole: bool, kd: usize) -> impl Iterator<Item = isize> + '_ {
    let n = path.len() as isize;
    (-1..=n - 1 - kd as isize).filter(move |&l| admissible(path, pinhole, l, (l + kd as isize + 1) as usize))
}

fn deletion_weight(kd: usize) -> f64 {
    match kd {
        0 => 0.25,
        1 => 0.5,
        _ => half_pow(kd + 1),
    }
}

/// 2^−j, exactly as `0.5f64.powi(j)` gives it (a power of two), without its loop: the
/// proposal densities sum these over every length up to `--max-depth`.
#[inline]
fn half_pow(j: usize) -> f64 {
    if j <= 1022 { f64::from_bits((1023 - j as u64) << 52) } else { 0.5f64.powi(j.min(i32::MAX as usize) as i32) }
}

/// Probability of deleting `kd` vertices after position `l` of `path`.
fn p_delete(path: &[PathVertex], pinhole: bool, kd: usize, l: isize) -> f64 {
    let n = path.len();
    let mut total = 0.0;
    let mut count_kd = 0;
    for k in 0..=n {
        let c = positions(path, pinhole, k).count();
        if c > 0 {
            total += deletion_weight(k);
        }
        if k == kd {
            count_kd = c;
        }
    }
    if count_kd == 0 || !admissible(path, pinhole, l, (l + kd as isize + 1) as usize) {
        return 0.0;
    }
    deletion_weight(kd) / total / count_kd as f64
}

fn addition_weight(kd: usize, ka: usize) -> f64 {
    match kd.abs_diff(ka) {
        0 => 0.5,
        1 => 0.2,
        j => 0.2 * half_pow(j),
    }
}

/// Probability of adding `ka` vertices after deleting `kd`, when `kept` vertices remain.
fn p_add(kd: usize, ka: usize, kept: usize, max_vertices: usize) -> f64 {
    let range = 2usize.saturating_sub(kept)..=max_vertices.saturating_sub(kept);
    if !range.contains(&ka) {
        return 0.0;
    }
    let total: f64 = range.map(|a| addition_weight(kd, a)).sum();
    addition_weight(kd, ka) / total
}

/// Samples an index ∝ `weights`.
fn pick(weights: &[f64], rng: &mut Pcg32) -> Option<usize> {
    let total: f64 = weights.iter().sum();
    if !(total > 0.0) {
        return None;
    }
    let mut u = rng.next_f64() * total;
    for (i, &w) in weights.iter().enumerate() {
        if u < w {
            return Some(i);
        }
        u -= w;
    }
    weights.iter().rposition(|&w| w > 0.0)
}

impl Bidirectional {
    /// `Q(ȳ|x̄)` for the path `y` made from a path of `n_from` vertices by deleting `kd` after
    /// position `l` and adding `ka` (with `from` the path it was made from, for the deletion
    /// probability): `p_d p_a Σ_i p_s′(i) / lum C*_{l+1+i}(ȳ)`.
    #[allow(clippy::too_many_arguments)]
    fn q(
        from: &[PathVertex],
        y_eval: &Evaluation,
        pinhole: bool,
        l: isize,
        kd: usize,
        ka: usize,
        max_vertices: usize,
    ) -> f64 {
        let kept = from.len() - kd;
        let p = p_delete(from, pinhole, kd, l) * p_add(kd, ka, kept, max_vertices);
        let first = (l + 1) as usize;
        p * y_eval.inverse_sum(first..=first + ka, |_| 1.0 / (ka + 1) as f64)
    }
}

impl Mutation for Bidirectional {
    fn name(&self) -> &'static str {
        "bidir"
    }

    fn applies(&self, _: &State) -> bool {
        true
    }

    fn propose(&self, cx: &Context, x: &State, rng: &mut Pcg32, stats: &mut RayStats) -> Option<Proposal> {
        let (scene, accel) = (cx.scene, cx.accel);
        let pinhole = scene.camera.is_pinhole();
        let xp = &x.path;
        let n = xp.len();
        // Deletion: length, then position.
        let kd_weights: Vec<f64> = (0..=n)
            .map(|kd| if positions(xp, pinhole, kd).next().is_some() { deletion_weight(kd) } else { 0.0 })
            .collect();
        let kd = pick(&kd_weights, rng)?;
        let pos: Vec<isize> = positions(xp, pinhole, kd).collect();
        let l = pos[rng.next_below(pos.len() as u32) as usize];
        let m = (l + kd as isize + 1) as usize;
        let kept = n - kd;
        // Addition: length, then how many from the light side.
        let ka_weights: Vec<f64> = (0..=cx.max_vertices.saturating_sub(kept))
            .map(|ka| if ka + kept >= 2 { addition_weight(kd, ka) } else { 0.0 })
            .collect();
        let ka = pick(&ka_weights, rng)?;
        let s_new = rng.next_below(ka as u32 + 1) as usize;
        let t_new = ka - s_new;
        // Light side.
        let mut light: Vec<PathVertex> = xp[..(l + 1) as usize].to_vec();
        if s_new > 0 {
            if light.is_empty() {
                light.push(sample_light_vertex(scene, rng)?);
                if !extend(scene, accel, rng, &mut light, s_new - 1, TransportMode::Importance, stats) {
                    return None;
                }
            } else if !extend(scene, accel, rng, &mut light, s_new, TransportMode::Importance, stats) {
                return None;
            }
        }
        // Camera side, walked from the lens.
        let mut eye: Vec<PathVertex> = xp[m..].iter().rev().copied().collect();
        if t_new > 0 {
            if eye.is_empty() {
                eye.push(PathVertex::lens(scene.camera.sample_lens(glam::vec2(rng.next_f32(), rng.next_f32()))));
                if !extend(scene, accel, rng, &mut eye, t_new - 1, TransportMode::Radiance, stats) {
                    return None;
                }
            } else if !extend(scene, accel, rng, &mut eye, t_new, TransportMode::Radiance, stats) {
                return None;
            }
        }
        if eye.is_empty() {
            return None;
        }
        let s = light.len();
        let mut path = light;
        path.extend(eye.iter().rev());
        let y_eval = evaluate(scene, &path, Forced::default());
        if y_eval.raster.is_none() || y_eval.lum(s) == 0.0 {
            return None;
        }
        if s > 0 && !visible(scene, accel, &path[s - 1], &path[s], stats) {
            return None;
        }
        let forward = Self::q(xp, &y_eval, pinhole, l, kd, ka, cx.max_vertices);
        let backward = Self::q(&path, &x.eval, pinhole, l, ka, kd, cx.max_vertices);
        let state = State { path, eval: y_eval };
        if !(forward > 0.0) {
            return Some(Proposal { state, accept: 0.0 });
        }
        Some(Proposal::with_ratio(state, backward, forward))
    }
}
