//! Mutation kernels of the MIR chains, behind one trait that returns a proposal together with
//! its transition density g(y|x) (papers/002 §5.2, §6; docs/design.md §3):
//!
//! * [`Bidirectional`] — path-space mutations in the spirit of Veach & Guibas' bidirectional
//!   mutation (papers/000 §3.5.3, Appendix B) specialised to MIR's paths `x₀ x₁ | x_v … y₀`:
//!   either the light sub-path is cut at a uniformly chosen vertex j (x_v is always deleted)
//!   and regenerated from y_{j−1} with a new length k (geometric, p = ½), or the camera end
//!   (x₀, x₁) is regenerated through a new image position. Each proposal is produced in exactly
//!   one way, so g(y|x) is the product of the choice probabilities and the area densities of
//!   the new vertices; the shared prefix cancels in every ratio.
//! * [`PrimarySample`] — Kelemen et al. 2002: the path is a deterministic function of a vector
//!   of uniform numbers; a proposal is a large step (all numbers redrawn, probability
//!   `p_large`) or a small step (each number moved by ±s₂·e^{−ln(s₂/s₁)ξ}, wrapped). Its target
//!   sums all light sub-path prefixes of the path and one extra number selects the VPL among
//!   them ∝ its share, so the VPL locations are still distributed ∝ Y(f^(c)).

use glam::{Vec2, vec2};

use super::mirpath::{CameraEnd, camera_end, contribution, extend_light, log_pdf_range, target, vertex_vpl};
use super::screen::ScreenGuide;
use super::set::Vpl;
use crate::accel::Accel;
use crate::path::{Vertex, light_subpath_with};
use crate::sampling::{Distribution1D, Pcg32, Sampler};
use crate::scene::{Camera, Scene};
use crate::stats::RayStats;

/// What a kernel needs to evaluate paths.
pub struct Context<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Its BVH.
    pub accel: &'a Accel,
    /// The camera the chain serves.
    pub camera: &'a Camera,
    /// How lights are chosen when a light sub-path starts (∝ power, or a light-source CDF).
    pub light_choice: &'a Distribution1D,
    /// Longest light sub-path (vertices).
    pub max_light: usize,
    /// Where the bidirectional kernel draws camera ends (uniform when `None`): the mixture of
    /// [`ScreenGuide::sample_mixture`], its density in every weight and proposal density.
    pub screen: Option<&'a ScreenGuide>,
}

impl Context<'_> {
    fn pixels(&self) -> f64 {
        self.camera.pixel_count() as f64
    }
}

/// A complete MIR path with what the chains need cached.
#[derive(Clone, Debug)]
pub struct PathState {
    /// Image position of x₁'s camera ray.
    pub raster: Vec2,
    /// Lens sample of x₁'s camera ray.
    pub lens: Vec2,
    /// Camera end.
    pub cam: CameraEnd,
    /// Light sub-path; the VPL is its vertex `vpl_index`.
    pub light: Vec<Vertex>,
    /// Index of x_v in `light`.
    pub vpl_index: usize,
    /// The VPL at x_v (unit scale: radiance of the light sub-path).
    pub vpl: Vpl,
    /// Unweighted contribution of the path through x_v.
    pub c: glam::Vec3,
    /// ln π(x).
    pub log_target: f64,
    /// Primary sample vector (primary-sample-space kernel only).
    pub u: Vec<f32>,
}

impl PathState {
    /// Light index of y₀ (which light the path comes from).
    pub fn source_light(&self) -> u32 {
        self.light[0].light
    }
}

/// A proposal and ln g(y|x).
pub struct Proposal {
    /// The proposed state, `None` when it has zero target (missed the scene, blocked...).
    pub state: Option<PathState>,
    /// ln g(y|x) (meaningless when `state` is `None`).
    pub log_g: f64,
}

/// The allocations of states a chain dropped, for its next proposals to build into: an MTMH
/// step makes 2p − 1 proposals and keeps at most one, and each proposal's light sub-path (and
/// primary samples) was a fresh allocation, about 2 % of a still Cornell frame's CPU time.
/// Also the step's candidate and weight lists.
#[derive(Default)]
pub struct Spare {
    lights: Vec<Vec<Vertex>>,
    samples: Vec<Vec<f32>>,
    /// MTMH's candidates and their log weights, and its reference log weights.
    pub(crate) candidates: Vec<(PathState, f64)>,
    pub(crate) weights: Vec<f64>,
    pub(crate) references: Vec<f64>,
}

impl Spare {
    /// Dropped allocations kept at most (a step drops at most 2p of them).
    const KEEP: usize = 64;

    /// An empty light sub-path.
    fn light(&mut self) -> Vec<Vertex> {
        let mut v = self.lights.pop().unwrap_or_default();
        v.clear();
        v
    }

    /// An empty primary sample vector.
    fn samples(&mut self) -> Vec<f32> {
        let mut v = self.samples.pop().unwrap_or_default();
        v.clear();
        v
    }

    fn give_light(&mut self, v: Vec<Vertex>) {
        if self.lights.len() < Self::KEEP && v.capacity() > 0 {
            self.lights.push(v);
        }
    }

    /// Takes back a state the chain no longer needs.
    pub fn recycle(&mut self, x: PathState) {
        self.give_light(x.light);
        if self.samples.len() < Self::KEEP && x.u.capacity() > 0 {
            self.samples.push(x.u);
        }
    }
}

/// A Metropolis mutation strategy over MIR paths.
pub trait MutationKernel: Send + Sync {
    /// Short name (`bidir`, `pss`).
    fn name(&self) -> &'static str;
    /// An independent sample and its importance weight π(x)/p(x) (an unbiased estimate of
    /// P_c, the total image luminance of the chain's path domain).
    fn independent(&self, ctx: &Context, rng: &mut Pcg32, stats: &mut RayStats) -> (Option<PathState>, f64);
    /// A proposal y ~ g(·|x), built in allocations from `spare`.
    fn propose(
        &self,
        ctx: &Context,
        x: &PathState,
        rng: &mut Pcg32,
        stats: &mut RayStats,
        spare: &mut Spare,
    ) -> Proposal;
    /// ln g(to|from).
    fn log_g(&self, ctx: &Context, to: &PathState, from: &PathState) -> f64;
    /// Re-evaluates a state for a (moved) camera; `None` when it left the domain.
    fn reevaluate(&self, ctx: &Context, x: &PathState, stats: &mut RayStats) -> Option<PathState>;
}

/// An image position (uniform, or from the context's [`ScreenGuide`] mixture) and a lens
/// sample.
fn camera_sample(ctx: &Context, rng: &mut Pcg32) -> (Vec2, Vec2) {
    let c = ctx.camera;
    let raster = match ctx.screen {
        None => vec2(rng.next_f32() * c.width as f32, rng.next_f32() * c.height as f32),
        Some(g) => g.sample_mixture([rng.next_f32(), rng.next_f32(), rng.next_f32()]),
    };
    (raster, vec2(rng.next_f32(), rng.next_f32()))
}

/// ln of the density [`camera_sample`] draws `raster` with, over the uniform density.
fn ln_camera_factor(ctx: &Context, raster: Vec2) -> f64 {
    ctx.screen.map_or(0.0, |g| (g.mixture_factor(raster) as f64).ln())
}

/// Geometric length distribution on 1..=kmax with ratio ½: ln p(k).
fn log_p_length(k: usize, kmax: usize) -> f64 {
    if k == 0 || k > kmax {
        return f64::NEG_INFINITY;
    }
    let norm = 1.0 - 0.5f64.powi(kmax as i32);
    -(k as f64) * std::f64::consts::LN_2 - norm.ln()
}

fn sample_length(kmax: usize, rng: &mut Pcg32) -> usize {
    let norm = 1.0 - 0.5f64.powi(kmax as i32);
    let mut u = rng.next_f64() * norm;
    let mut k = 1;
    let mut p = 0.5;
    while k < kmax && u >= p {
        u -= p;
        p *= 0.5;
        k += 1;
    }
    k
}

/// Survival ratio of the light sub-path length of independent samples (their prefixes are all
/// used): P(K = k) ∝ PREFIX_RATIO^(k−1) on 1..=kmax, about four vertices on average.
const PREFIX_RATIO: f64 = 0.75;

/// P(K ≥ j) for the length K of [`sample_prefix_length`].
fn prefix_survival(j: usize, kmax: usize) -> f64 {
    let tail = PREFIX_RATIO.powi(kmax as i32);
    (PREFIX_RATIO.powi(j as i32 - 1) - tail) / (1.0 - tail)
}

/// A length K on 1..=kmax with P(K = k) ∝ [`PREFIX_RATIO`]^(k−1).
fn sample_prefix_length(kmax: usize, rng: &mut Pcg32) -> usize {
    let u = rng.next_f64();
    (1..kmax).find(|&k| u >= prefix_survival(k + 1, kmax)).unwrap_or(kmax)
}

/// An [`Pcg32`] seen as a [`Sampler`].
struct RngSampler<'a>(&'a mut Pcg32);

impl Sampler for RngSampler<'_> {
    fn next_1d(&mut self) -> f32 {
        self.0.next_f32()
    }
}

/// The path-space kernel (see the module doc).
#[derive(Clone, Debug)]
pub struct Bidirectional {
    /// Probability of regenerating the camera end instead of the light sub-path.
    pub p_camera: f64,
}

impl Default for Bidirectional {
    fn default() -> Self {
        Bidirectional { p_camera: 0.25 }
    }
}

impl Bidirectional {
    /// ln π of a path: Y(N_pix · C*) times the path's density (the density cancels in MH ratios
    /// against g; it is kept so MTMH weights of different mutation types are comparable).
    fn log_target(ctx: &Context, c: glam::Vec3, light: &[Vertex], cam: &CameraEnd) -> f64 {
        let y = target(c) * ctx.pixels();
        if y <= 0.0 {
            return f64::NEG_INFINITY;
        }
        y.ln() + log_pdf_range(light, 0, light.len()) + cam.log_pdf
    }

    fn build(
        ctx: &Context,
        raster: Vec2,
        lens: Vec2,
        cam: CameraEnd,
        light: Vec<Vertex>,
        stats: &mut RayStats,
    ) -> Option<PathState> {
        let vpl_index = light.len() - 1;
        let vpl = vertex_vpl(ctx.scene, &light, vpl_index)?;
        let c = contribution(ctx.scene, ctx.accel, &cam, &vpl, stats);
        let log_target = Self::log_target(ctx, c, &light, &cam);
        if !log_target.is_finite() {
            return None;
        }
        Some(PathState { raster, lens, cam, light, vpl_index, vpl, c, log_target, u: Vec::new() })
    }

    fn common_prefix(a: &[Vertex], b: &[Vertex]) -> usize {
        a.iter().zip(b).take_while(|(x, y)| x.p == y.p && x.kind == y.kind).count()
    }
}

impl MutationKernel for Bidirectional {
    fn name(&self) -> &'static str {
        "bidir"
    }

    /// One light sub-path of K vertices (P(K ≥ j) = [`prefix_survival`]), every prefix of it
    /// connected to one camera end: the sample's weight is Σ_j π(x_j) / (P(K ≥ j) q(x_j)) over
    /// its prefixes x_j (each an unbiased estimate of the length-j part of P_c, so the sum
    /// estimates P_c), and the state it returns is one prefix chosen ∝ its term. Choosing one
    /// length per sample instead (as the light sub-path mutation does) multiplies the
    /// estimate's relative variance by 1/p(k) where light needs k vertices to reach what the
    /// camera sees: measured on ajar-door-thick (64×48), the spread of P̂_c from a million
    /// samples fell from 12 % to 5.1 % (the variance by 5.6×) for about twice the rays per
    /// sample (issue 19; `examples/mir_bias.rs … pc`).
    fn independent(&self, ctx: &Context, rng: &mut Pcg32, stats: &mut RayStats) -> (Option<PathState>, f64) {
        let (raster, lens) = camera_sample(ctx, rng);
        let Some(cam) = camera_end(ctx.scene, ctx.accel, ctx.camera, raster, lens, stats) else { return (None, 0.0) };
        let k = sample_prefix_length(ctx.max_light, rng);
        let mut light = Vec::with_capacity(k);
        // A walk that ends early still gives its prefixes (their density does not depend on
        // what came after them).
        let _ = extend_light(ctx.scene, ctx.accel, ctx.light_choice, &mut light, k, &mut RngSampler(rng), stats);
        let mut total = 0.0;
        let mut terms: Vec<(usize, f64)> = Vec::with_capacity(light.len());
        for j in 0..light.len() {
            let Some(vpl) = vertex_vpl(ctx.scene, &light, j) else { continue };
            let y = target(contribution(ctx.scene, ctx.accel, &cam, &vpl, stats));
            if y > 0.0 {
                total += y / prefix_survival(j + 1, ctx.max_light);
                terms.push((j, total));
            }
        }
        if !(total > 0.0 && total.is_finite()) {
            return (None, 0.0);
        }
        let pick = rng.next_f64() * total;
        let j = terms.iter().find(|t| t.1 > pick).unwrap_or(terms.last().expect("total > 0")).0;
        light.truncate(j + 1);
        let x = Self::build(ctx, raster, lens, cam, light, stats);
        (x, total * ctx.pixels() / (ln_camera_factor(ctx, raster)).exp())
    }

    fn propose(
        &self,
        ctx: &Context,
        x: &PathState,
        rng: &mut Pcg32,
        stats: &mut RayStats,
        spare: &mut Spare,
    ) -> Proposal {
        let invalid = Proposal { state: None, log_g: 0.0 };
        if rng.next_f64() < self.p_camera {
            let (raster, lens) = camera_sample(ctx, rng);
            let Some(cam) = camera_end(ctx.scene, ctx.accel, ctx.camera, raster, lens, stats) else { return invalid };
            let log_g = self.p_camera.ln() + cam.log_pdf + ln_camera_factor(ctx, raster);
            let mut light = spare.light();
            light.extend_from_slice(&x.light);
            let state = Self::build(ctx, raster, lens, cam, light, stats);
            return Proposal { state, log_g };
        }
        let s = x.light.len();
        let j = (rng.next_f64() * s as f64) as usize % s;
        let kmax = ctx.max_light - j;
        let k = sample_length(kmax, rng);
        let mut light = spare.light();
        light.extend_from_slice(&x.light[..j]);
        if !extend_light(ctx.scene, ctx.accel, ctx.light_choice, &mut light, k, &mut RngSampler(rng), stats) {
            spare.give_light(light);
            return invalid;
        }
        let log_g =
            (1.0 - self.p_camera).ln() - (s as f64).ln() + log_p_length(k, kmax) + log_pdf_range(&light, j, j + k);
        let state = Self::build(ctx, x.raster, x.lens, x.cam, light, stats);
        Proposal { state, log_g }
    }

    fn log_g(&self, ctx: &Context, to: &PathState, from: &PathState) -> f64 {
        let j = Self::common_prefix(&to.light, &from.light);
        if j == to.light.len() && j == from.light.len() {
            // Same light sub-path: a camera-end regeneration.
            return self.p_camera.ln() + to.cam.log_pdf + ln_camera_factor(ctx, to.raster);
        }
        if to.raster != from.raster || to.lens != from.lens || j >= from.light.len() {
            return f64::NEG_INFINITY;
        }
        let s = from.light.len();
        let kmax = ctx.max_light - j;
        let k = to.light.len() - j;
        (1.0 - self.p_camera).ln() - (s as f64).ln()
            + log_p_length(k, kmax)
            + log_pdf_range(&to.light, j, to.light.len())
    }

    fn reevaluate(&self, ctx: &Context, x: &PathState, stats: &mut RayStats) -> Option<PathState> {
        let cam = camera_end(ctx.scene, ctx.accel, ctx.camera, x.raster, x.lens, stats)?;
        Self::build(ctx, x.raster, x.lens, cam, x.light.clone(), stats)
    }
}

/// The primary-sample-space kernel of Kelemen et al. 2002 (see the module doc).
#[derive(Clone, Debug)]
pub struct PrimarySample {
    /// Probability of a large step.
    pub p_large: f64,
    /// Smallest small-step size s₁.
    pub s1: f32,
    /// Largest small-step size s₂.
    pub s2: f32,
}

impl Default for PrimarySample {
    fn default() -> Self {
        PrimarySample { p_large: 0.3, s1: 1.0 / 1024.0, s2: 1.0 / 64.0 }
    }
}

/// Replays a primary sample vector.
struct Replay<'a> {
    u: &'a [f32],
    i: usize,
}

impl Sampler for Replay<'_> {
    fn next_1d(&mut self) -> f32 {
        let v = self.u.get(self.i).copied().unwrap_or(0.5);
        self.i += 1;
        v
    }
}

/// Camera (4) + VPL selection (1) + light start (5) + per further vertex (lobe, 2D, roulette).
fn dims(max_light: usize) -> usize {
    10 + 4 * max_light
}

impl PrimarySample {
    /// Evaluates the path of primary samples `u`.
    fn eval(&self, ctx: &Context, u: Vec<f32>, mut light: Vec<Vertex>, stats: &mut RayStats) -> Option<PathState> {
        let c = ctx.camera;
        let raster = vec2(u[0] * c.width as f32, u[1] * c.height as f32);
        let lens = vec2(u[2], u[3]);
        let cam = camera_end(ctx.scene, ctx.accel, ctx.camera, raster, lens, stats)?;
        let mut replay = Replay { u: &u[5..], i: 0 };
        light_subpath_with(ctx.scene, ctx.accel, ctx.light_choice, &mut replay, ctx.max_light, &mut light, stats);
        if light.is_empty() {
            return None;
        }
        // Every prefix's x_v is a candidate VPL; the target sums them all.
        let mut parts: Vec<(usize, Vpl, glam::Vec3, f64)> = Vec::with_capacity(light.len());
        let mut total = 0.0;
        for i in 0..light.len() {
            let Some(vpl) = vertex_vpl(ctx.scene, &light, i) else { continue };
            let cc = contribution(ctx.scene, ctx.accel, &cam, &vpl, stats);
            let y = target(cc);
            if y > 0.0 {
                total += y;
                parts.push((i, vpl, cc, total));
            }
        }
        if total <= 0.0 {
            return None;
        }
        let pick = u[4] as f64 * total;
        let &(vpl_index, vpl, cc, _) = parts.iter().find(|p| p.3 > pick).unwrap_or(parts.last().expect("total > 0"));
        let log_target = (total * ctx.pixels()).ln();
        Some(PathState { raster, lens, cam, light, vpl_index, vpl, c: cc, log_target, u })
    }

    fn small_step_log_density(&self, from: f32, to: f32) -> f64 {
        let mut d = (to - from).abs();
        d = d.min(1.0 - d);
        if d < self.s1 * 0.999 || d > self.s2 * 1.001 {
            return f64::NEG_INFINITY;
        }
        -((2.0 * d as f64) * (self.s2 as f64 / self.s1 as f64).ln()).ln()
    }
}

impl MutationKernel for PrimarySample {
    fn name(&self) -> &'static str {
        "pss"
    }

    fn independent(&self, ctx: &Context, rng: &mut Pcg32, stats: &mut RayStats) -> (Option<PathState>, f64) {
        let u: Vec<f32> = (0..dims(ctx.max_light)).map(|_| rng.next_f32()).collect();
        match self.eval(ctx, u, Vec::new(), stats) {
            Some(x) => {
                let w = x.log_target.exp();
                (Some(x), w)
            }
            None => (None, 0.0),
        }
    }

    fn propose(
        &self,
        ctx: &Context,
        x: &PathState,
        rng: &mut Pcg32,
        stats: &mut RayStats,
        spare: &mut Spare,
    ) -> Proposal {
        let mut u = spare.samples();
        if rng.next_f64() < self.p_large {
            u.extend((0..x.u.len()).map(|_| rng.next_f32()));
        } else {
            let ln_ratio = (self.s2 / self.s1).ln();
            u.extend(
                x.u.iter()
                    .map(|&v| {
                        let step = self.s2 * (-ln_ratio * rng.next_f32()).exp();
                        let v = if rng.next_f32() < 0.5 { v + step } else { v - step };
                        v - v.floor()
                    })
                    .map(|v| if v >= 1.0 { 0.0 } else { v }),
            );
        }
        let state = self.eval(ctx, u, spare.light(), stats);
        let log_g = match &state {
            Some(y) => self.log_g(ctx, y, x),
            None => 0.0,
        };
        Proposal { state, log_g }
    }

    fn log_g(&self, _ctx: &Context, to: &PathState, from: &PathState) -> f64 {
        let small: f64 = to.u.iter().zip(&from.u).map(|(&b, &a)| self.small_step_log_density(a, b)).sum();
        // g = p_large · 1 + (1 − p_large) · Π k(Δ), in log space.
        let a = self.p_large.ln();
        let b = (1.0 - self.p_large).ln() + small;
        let m = a.max(b);
        m + ((a - m).exp() + (b - m).exp()).ln()
    }

    fn reevaluate(&self, ctx: &Context, x: &PathState, stats: &mut RayStats) -> Option<PathState> {
        self.eval(ctx, x.u.clone(), Vec::new(), stats)
    }
}
