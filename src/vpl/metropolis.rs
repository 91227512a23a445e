//! Metropolis instant radiosity (Segovia, Iehl & Péroche 2007; papers/002, DESIGN §3): a Markov
//! chain over complete paths with stationary density ∝ Y(f^(c)), whose VPL locations are then
//! normalised so that each brings its share of the camera power.
//!
//! Per call of [`Mir::sample`]:
//! 1. **P_c** (§5.1): N independent bidirectional samples of the kernel's own generator; their
//!    mean weight estimates P_c, and each chain's first state is drawn among them ∝ weight
//!    (removing start-up bias, Veach & Guibas 1997). When the camera has not jumped, a chain
//!    continues from its last state instead (temporal coherence, DESIGN §3.6).
//! 2. **Chains** (§5.2, §6.1): MH, or MTMH with p candidates and λ(u, v) = [g(u|v) g(v|u)]⁻¹, so
//!    that w(u, v) = π(v) / g(v|u). [`MirSettings::chains`] independent chains (2 by default,
//!    one per core here) run in parallel, each for its share of the m locations; their states
//!    all sample the same target, so pooled they are one sample of it (the paper runs one chain;
//!    one serial chain left a core idle for half of an interactive frame's VPL stage).
//! 3. **Geographical VPLs** (§5.3): consecutive states of a chain with the same x_v add to its
//!    count k; a chain runs for a state count fixed from earlier runs' move rate (or until its
//!    share of locations exists, or a documented step bound is hit); n = number of states of
//!    all chains.
//! 4. **Normalisation** (§5.4, §5.5): location i brings P_i = k_i P_c / n. Its camera response
//!    P'_i is estimated with K camera probes (first surfaces of stratified camera rays) for the
//!    VPL's own radiance L̂_i (the light sub-path's), and the VPL's radiance becomes
//!    L̂_i · P_i / P'_i. The unshadowed response is summed over every probe; when many probes
//!    are lit, only the visible fraction is sampled, with
//!    [`MirSettings::visibility_samples`] shadow rays placed ∝ the unshadowed response: the
//!    same expectation from a third of the rays, with P̂′'s variance 1 % higher on Cornell and
//!    35 % on Sponza (whose VPLs are hidden from more probes); P̂′'s own spread is a small part
//!    of a VPL's, whose count k_i is a handful of chain states, and the images' error after 64
//!    frames did not change (benches/results/2026-12-02-view.md). Because 1/P̂' overestimates
//!    1/P' (by ≈ CV²/K), a VPL seen by fewer than `min_probe_hits` probes is measured with
//!    further probe batches, and the second-order term σ̂²/P̂'³ is subtracted; what bias
//!    remains vanishes as probes grow (MIR is consistent). For a diffuse x_v this is the
//!    paper's (P_i / P'_i)·chroma_i with the unit emitter tinted by the VPL's own colour, so
//!    colour survives the luminance-driven chain exactly; for glossy x_v the VPL keeps its lobe.
//!
//! # Where light went missing (issue 19)
//!
//! Measured on the hard-visibility scenes (`ajar-door-thick`, `light-box-thick`,
//! `deep-shaft`; 64×48, 8 seeds × 8 frames of 256 VPLs, against pt at 8192 spp;
//! `cargo run --release --example mir_bias -- SCENE 64 48 8 8 8192 [pc]`), each cause with the
//! share of the reference's light it cost and what was done about it:
//!
//! | cause | ajar-door-thick | light-box-thick | deep-shaft | fix |
//! |---|--:|--:|--:|---|
//! | The chains' target bounds G at [`super::mirpath::TARGET_CLAMP`] (needed: an unbounded target sticks at VPLs next to x₁). Its integral P_c is then the *clamped* image, and a VPL next to the surfaces it lights (the faces of a slit, of a tunnel) has a clamped response far below its real one: with `--clamp 0` that light came back only through the rare VPLs whose P_i/P′_i ratio is huge, a tail no run of a few seconds samples | 30 % (P_c = 0.70 × pt from 8·10⁶ samples) | 13 % (0.87) | 1 % | the gather clamps at a bound ≥ the target's and the clamp is compensated ([`crate::gather::compensate`], Kollig & Keller 2004): same expectation, finite variance |
//! | The radiance cap (200 × the median VPL) removed the VPLs that light the slit's surroundings | 80 % of VPL radiance, image 0.49 → 0.61 × pt | 38 % of radiance | 12 % of radiance | removed; [`ChainReport::max_over_median`] reports the spread instead |
//! | P̂_c from N = 4096 independent samples is skewed (light reaches what the camera sees on one light path in ~10³–10⁴): its median is below its mean, so a typical run is dark though the mean over seeds is right. Spread of the image mean over seeds (8 frames each), before → after | 32 % → 31 % | 50 % → 51 % | 17 % → 5 % | the bidirectional kernel's independent samples use every prefix of their light sub-path ([`Bidirectional`](super::mutation::Bidirectional)): P̂_c's variance 5.6× lower on ajar-door-thick. On the slit and the box the spread is then dominated by the VPLs themselves (radiance up to 4·10⁵ × the median: VPLs that light a few pixels next to an opening), not by P̂_c; this is MIR's main remaining error there (see the README) |
//! | The clamp compensation estimated the light of the surfaces next to a receiver with MIR's own VPLs (Kollig & Keller's recursion). MIR places VPLs ∝ their response to the camera, so surfaces the camera does not see (the faces of the slit, of the tunnels) are lit only by rare VPLs of huge weight (max/median 8·10⁵) or by none: the residual came out at half of what the clamp removed | 15 % (residual 0.157 of the 0.30 removed; 32×24, 32 seeds × 16 frames) | 11 % (default render 0.87 → 0.97 × pt, 8 seeds) | — (0.92 both ways, within pt's own ± 2.8 %) | the residual's reflected light is path traced ([`crate::gather::compensate`]): 0.287 recovered, image 0.983 ± 0.031 × pt (bidir), 0.995 ± 0.021 (pss) |
//! | VPLs no probe saw (dropped) | 0.02 % | 0.4–0.7 % | 0 | left: below the noise; [`ChainReport::dropped_share`] reports it |
//! | Light sub-paths longer than `max_light` = 16 vertices, first-vertex restrictions | not measurable (P_c from 10⁶ samples agrees with pt restricted to ≤ 17 edges within 1–2 %) | | | — |
//!
//! With the fixes, MTMH and MH with both kernels agree with pt in image mean and per 8×8 block
//! on the three scenes over 8 seeds (`tests/mir.rs`,
//! `compensated_mir_agrees_with_pt_on_the_hard_scenes`), and so does the default render on
//! every built-in diffuse scene (`the_default_render_agrees_with_pt_on_every_diffuse_scene`);
//! the spread over seeds stays large. (The primary-sample kernel's mean on the slit scene,
//! 0.80–0.87 × pt before the path-traced residual, was the same missing residual: 0.995 ±
//! 0.021 after it over 32 seeds.)

use std::sync::OnceLock;
use std::time::Instant;

use rayon::prelude::*;

use super::cdf::light_cdf;
use super::mutation::{Bidirectional, Context, MutationKernel, PathState, PrimarySample, Spare};
use super::screen::{ProbeDensity, ScreenGuide};
use super::set::{Vpl, VplSet};
use super::transfer::Receiver;
use super::{SamplerStats, VplSampler};
use crate::accel::Accel;
use crate::color::luminance;
use crate::gather::shade::{Prepared, ShadowBatch, VplLanes};
use crate::sampling::{Distribution1D, IndependentSampler, Pcg32, Sampler};
use crate::scene::{Camera, Scene};
use crate::stats::RayStats;

/// MH or MTMH.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Chain {
    /// Metropolis–Hastings.
    Mh,
    /// Multiple-try Metropolis–Hastings with this many candidates.
    Mtmh(usize),
}

/// When a chain run stops.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopRule {
    /// After a number of states n fixed before the run (m / the rate at which earlier runs moved
    /// to a new location), so about m locations. n does not depend on the run it normalises,
    /// which keeps the estimate unbiased (the default). A sampler's first run has no rate yet
    /// and stops at m locations.
    States,
    /// As soon as m distinct locations exist (papers/002 §5.3). n then depends on the run: runs
    /// that move fast stop early, which biases the image towards where the chain moves fast
    /// (measured: several % in cornell's corners with MH); kept for comparison.
    Locations,
}

/// Settings of the MIR samplers.
#[derive(Clone, Debug, PartialEq)]
pub struct MirSettings {
    /// MH or MTMH (default 10 candidates).
    pub chain: Chain,
    /// Independent samples estimating P_c (N), at least; a run takes up to four times as many
    /// when the previous run's P̂_c had a relative standard error above
    /// [`Self::pc_target_error`] (N decided before the run, so P̂_c keeps its expectation).
    pub pc_samples: usize,
    /// Relative standard error of P̂_c the sample count adapts to.
    pub pc_target_error: f64,
    /// Camera probes per batch estimating each VPL's camera response (K).
    pub probes: usize,
    /// Share of each probe batch placed ∝ where the chains' camera vertices fell (the rest is
    /// stratified over the image), and whether the bidirectional kernel's camera ends follow
    /// the previous run's [`ScreenGuide`]; see [`super::screen`]. 0: both uniform.
    pub guided_probes: f64,
    /// Probe batches available; a VPL seen by fewer than `min_probe_hits` probes of the first
    /// batches is measured with the next batch, up to this many.
    pub probe_batches: usize,
    /// Probe hits a VPL's response estimate should rest on.
    pub min_probe_hits: usize,
    /// Shadow rays a VPL's response takes from one probe batch: its lit probes are all traced
    /// when there are at most this many, otherwise this many visibility samples are placed
    /// among them ∝ their unshadowed response (see `visibility_samples`).
    pub visibility_samples: usize,
    /// Longest light sub-path (vertices).
    pub max_light: usize,
    /// Choose lights with a light-source CDF (§7.4) instead of ∝ power.
    pub light_cdf: bool,
    /// The chain stops after `max_steps_per_vpl · m` states even if fewer than m locations
    /// exist (a warning is reported).
    pub max_steps_per_vpl: usize,
    /// When a run stops.
    pub stop: StopRule,
    /// Continue each chain from its last state while the camera stands still (else every run
    /// starts its chains from fresh picks of the P_c samples).
    pub carry: bool,
    /// Independent chains run side by side (in parallel), each giving ⌈m/chains⌉ or ⌊m/chains⌋
    /// of the m locations. Their pooled states estimate the same target, so the normalisation
    /// is unchanged; the chain count, not the thread count, fixes the result.
    pub chains: usize,
}

impl MirSettings {
    /// MTMH with 10 candidates, N = 4096, K = 1024, light paths ≤ 16 vertices.
    pub fn mtmh() -> Self {
        MirSettings {
            chain: Chain::Mtmh(10),
            pc_samples: 4096,
            pc_target_error: 0.05,
            probes: 1024,
            guided_probes: 0.5,
            probe_batches: 16,
            min_probe_hits: 256,
            visibility_samples: 256,
            max_light: 16,
            light_cdf: false,
            max_steps_per_vpl: 64,
            stop: StopRule::States,
            carry: false,
            chains: 64,
        }
    }

    /// Plain MH with the same budgets.
    pub fn mh() -> Self {
        MirSettings { chain: Chain::Mh, ..Self::mtmh() }
    }
}

/// What one chain run produced, beyond the VPL set.
#[derive(Clone, Debug, Default)]
pub struct ChainReport {
    /// Estimated camera power P_c (sum over pixels of luminance).
    pub pc: f64,
    /// Samples P̂_c took.
    pub pc_samples: usize,
    /// P̂_c's relative standard error, from its samples.
    pub pc_error: f64,
    /// Chain states n.
    pub states: u64,
    /// Distinct locations m.
    pub locations: usize,
    /// Power P_i of each location, by the light its paths start from.
    pub power_by_light: Vec<f64>,
    /// The chain hit its step bound before m locations.
    pub truncated: bool,
    /// P_c is zero: no light reaches what the camera sees through the chain's domain.
    pub dark: bool,
    /// Locations left out because no probe saw them (P̂′ = 0).
    pub dropped: usize,
    /// Share of the run's power Σ P_i those locations had.
    pub dropped_share: f64,
    /// Largest VPL radiance (luminance) over the median.
    pub max_over_median: f64,
}

/// The MIR VPL sampler over a mutation kernel.
pub struct Mir<K: MutationKernel> {
    /// The mutation kernel.
    pub kernel: K,
    /// Settings.
    pub settings: MirSettings,
    states: Vec<PathState>,
    jumped: bool,
    cdf: Option<(Camera, Distribution1D)>,
    move_rate: f64,
    runs: u64,
    /// Where the last run's camera vertices fell, guiding this run's camera ends.
    guide: Option<ScreenGuide>,
    /// P_c samples of the next run (see [`MirSettings::pc_samples`]).
    pc_next: usize,
    /// Report of the last call.
    pub last: ChainReport,
}

/// MIR with the path-space bidirectional kernel.
pub type MirBidir = Mir<Bidirectional>;
/// MIR with the primary-sample-space kernel.
pub type MirPss = Mir<PrimarySample>;

impl<K: MutationKernel> Mir<K> {
    /// A sampler with no chain yet.
    pub fn new(kernel: K, settings: MirSettings) -> Self {
        Mir {
            kernel,
            settings,
            states: Vec::new(),
            jumped: true,
            cdf: None,
            move_rate: 0.5,
            runs: 0,
            guide: None,
            pc_next: 0,
            last: ChainReport::default(),
        }
    }
}

const TAG_PC: u64 = 0x0050_435f_5341_4d50;
const TAG_CHAIN: u64 = 0x0043_4841_494e;
const TAG_PROBE: u64 = 0x0050_524f_4245;
const TAG_VISIBILITY: u64 = 0x0056_4953_4942;

fn log_sum_exp(v: &[f64]) -> f64 {
    let m = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if m == f64::NEG_INFINITY {
        return m;
    }
    m + v.iter().map(|x| (x - m).exp()).sum::<f64>().ln()
}

/// Estimates P_c with `n` independent samples and returns it with one of them drawn ∝ weight.
pub fn estimate_pc<K: MutationKernel>(
    kernel: &K,
    ctx: &Context,
    n: usize,
    seed: u64,
    stats: &mut RayStats,
) -> (f64, Option<PathState>) {
    let (pc, picks, _) = estimate_pc_picks(kernel, ctx, n, 1, seed, stats);
    (pc, picks.into_iter().next())
}

/// [`estimate_pc`] with `picks` independent draws ∝ weight (none when P_c = 0): the starting
/// states of that many chains; and the estimate's relative standard error (from the weights'
/// sample variance; 0 when P_c = 0).
pub fn estimate_pc_picks<K: MutationKernel>(
    kernel: &K,
    ctx: &Context,
    n: usize,
    picks: usize,
    seed: u64,
    stats: &mut RayStats,
) -> (f64, Vec<PathState>, f64) {
    // Only the weights are kept: a chosen sample is drawn again from its own stream (the same
    // state, bit for bit). Keeping all n states cost an allocation and a copy of each path
    // when a still camera's chains continue and pick none.
    let stream = |i: u64| Pcg32::from_words(&[seed, TAG_PC, i]);
    let results: Vec<(f64, RayStats)> = (0..n)
        .into_par_iter()
        .map(|i| {
            let mut st = RayStats::default();
            let (_, w) = kernel.independent(ctx, &mut stream(i as u64), &mut st);
            (if w.is_finite() { w } else { 0.0 }, st)
        })
        .collect();
    let total: f64 = results.iter().map(|r| r.0).sum();
    for r in &results {
        *stats += r.1;
    }
    if !(total > 0.0) {
        return (0.0, Vec::new(), 0.0);
    }
    let mean = total / n as f64;
    let var = results.iter().map(|r| (r.0 - mean).powi(2)).sum::<f64>() / (n as f64 - 1.0).max(1.0);
    let rel_se = (var / n as f64).sqrt() / mean;
    // A sample has a positive weight exactly when it has a state.
    let chosen = (0..picks as u64)
        .filter_map(|j| {
            let mut rng = Pcg32::from_words(&[seed, TAG_PC, u64::MAX - j]);
            let mut pick = rng.next_f64() * total;
            let mut chosen = None;
            for (i, (w, _)) in results.iter().enumerate() {
                if *w > 0.0 {
                    chosen = Some(i);
                    if pick < *w {
                        break;
                    }
                    pick -= w;
                }
            }
            chosen.and_then(|i| kernel.independent(ctx, &mut stream(i as u64), &mut RayStats::default()).0)
        })
        .collect();
    (mean, chosen, rel_se)
}

/// What one chain produced in a run.
struct ChainRun {
    /// Consecutive states grouped by VPL location: (first state, number of states).
    locations: Vec<(PathState, u64)>,
    proposed: u64,
    accepted: u64,
    /// The state the next run continues from.
    last: PathState,
    /// The chain hit its step bound before its share of locations.
    truncated: bool,
    rays: RayStats,
    /// Image position of every state's camera vertex (for [`ProbeDensity`]).
    rasters: Vec<glam::Vec2>,
}

/// Runs one chain from `x` for `m` locations (or `fixed_states` states, see [`StopRule`]).
fn run_chain<K: MutationKernel>(
    kernel: &K,
    ctx: &Context,
    chain: Chain,
    mut x: PathState,
    m: usize,
    stop: StopRule,
    fixed_states: u64,
    max_states: u64,
    mut rng: Pcg32,
) -> ChainRun {
    let mut rays = RayStats::default();
    let mut locations: Vec<(PathState, u64)> = Vec::with_capacity(m);
    let (mut proposed, mut accepted) = (0u64, 0u64);
    let mut truncated = false;
    let mut n = 0u64;
    let mut spare = Spare::default();
    let mut rasters = Vec::with_capacity(fixed_states.min(max_states) as usize);
    loop {
        rasters.push(x.raster);
        match locations.last_mut() {
            Some((s, k)) if s.vpl.position == x.vpl.position && s.vpl.normal == x.vpl.normal => *k += 1,
            _ => {
                if stop == StopRule::Locations && locations.len() == m {
                    break;
                }
                locations.push((x.clone(), 1));
            }
        }
        n += 1;
        if n >= fixed_states {
            truncated = n >= max_states && locations.len() < m;
            break;
        }
        let (next, acc) = step(kernel, ctx, chain, x, &mut rng, &mut rays, &mut spare);
        proposed += 1;
        accepted += acc as u64;
        x = next;
    }
    // (Locations rule: the last state opened location m + 1 and is not counted.)
    ChainRun { locations, proposed, accepted, last: x, truncated, rays, rasters }
}

/// One MH or MTMH transition from `x`; returns the next state and whether a move was accepted.
/// States it drops go back to `spare`, whose allocations its proposals build into.
pub fn step<K: MutationKernel>(
    kernel: &K,
    ctx: &Context,
    chain: Chain,
    x: PathState,
    rng: &mut Pcg32,
    stats: &mut RayStats,
    spare: &mut Spare,
) -> (PathState, bool) {
    match chain {
        Chain::Mh => {
            let p = kernel.propose(ctx, &x, rng, stats, spare);
            let Some(y) = p.state else { return (x, false) };
            let log_a = y.log_target + kernel.log_g(ctx, &x, &y) - x.log_target - p.log_g;
            if log_a >= 0.0 || rng.next_f64().ln() < log_a {
                spare.recycle(x);
                (y, true)
            } else {
                spare.recycle(y);
                (x, false)
            }
        }
        Chain::Mtmh(p) => {
            // Step 1–2: p candidates from g(·|x), one chosen ∝ w(x, y) = π(y) / g(y|x).
            let mut ys = std::mem::take(&mut spare.candidates);
            ys.clear();
            for _ in 0..p.max(1) {
                let pr = kernel.propose(ctx, &x, rng, stats, spare);
                if let Some(y) = pr.state {
                    let lw = y.log_target - pr.log_g;
                    if lw.is_finite() {
                        ys.push((y, lw));
                    } else {
                        spare.recycle(y);
                    }
                }
            }
            if ys.is_empty() {
                spare.candidates = ys;
                return (x, false);
            }
            let mut lws = std::mem::take(&mut spare.weights);
            lws.clear();
            lws.extend(ys.iter().map(|(_, lw)| *lw));
            let num = log_sum_exp(&lws);
            // Choose j ∝ w, with weights normalised in log space (no overflow).
            let mut pick = rng.next_f64();
            let mut j = ys.len() - 1;
            for (k, lw) in lws.iter().enumerate() {
                let w = (lw - num).exp();
                if pick < w {
                    j = k;
                    break;
                }
                pick -= w;
            }
            // Step 3: p − 1 reference points from g(·|y_j), plus x itself.
            let mut refs = std::mem::take(&mut spare.references);
            refs.clear();
            let yj = &ys[j].0;
            for _ in 0..p.max(1) - 1 {
                let pr = kernel.propose(ctx, yj, rng, stats, spare);
                if let Some(z) = pr.state {
                    let lw = z.log_target - pr.log_g;
                    spare.recycle(z);
                    if lw.is_finite() {
                        refs.push(lw);
                    }
                }
            }
            refs.push(x.log_target - kernel.log_g(ctx, &x, yj));
            // Step 4–5: generalised ratio.
            let den = log_sum_exp(&refs);
            let log_r = num - den;
            let next = if log_r >= 0.0 || rng.next_f64().ln() < log_r {
                let (y, _) = ys.swap_remove(j);
                spare.recycle(x);
                (y, true)
            } else {
                (x, false)
            };
            for (y, _) in ys.drain(..) {
                spare.recycle(y);
            }
            (spare.candidates, spare.weights, spare.references) = (ys, lws, refs);
            next
        }
    }
}

/// One batch of camera probes placed by `density`: first surfaces of camera rays (the §5.5
/// radiance pass). Returns the receivers, their pixels and balance weights, and the number of
/// rays traced (misses and specular hits count as zero response).
fn probes(ctx: &Context, density: &ProbeDensity, seed: u64, parallel: bool) -> ProbeBatch {
    let cam = ctx.camera;
    let probe = |i: usize| {
        let mut st = RayStats::default();
        let mut s = IndependentSampler::for_stream(seed, TAG_PROBE, i as u64);
        let raster = density.raster(i, [s.next_1d(), s.next_1d(), s.next_1d(), s.next_1d()]);
        let c = super::mirpath::camera_end(ctx.scene, ctx.accel, cam, raster, s.next_2d(), &mut st);
        let pixel = [(raster.x as u32).min(cam.width - 1), (raster.y as u32).min(cam.height - 1)];
        (c.map(|c| (c.receiver, Prepared::new(ctx.scene, &c.receiver), pixel, density.weight(raster))), st)
    };
    /// A probe's receiver, prepared, its pixel and its weight, when its ray found a surface.
    type Probe = Option<(Receiver, Prepared, [u32; 2], f32)>;
    let n = density.count();
    let traced: Vec<(Probe, RayStats)> =
        if parallel { (0..n).into_par_iter().map(probe).collect() } else { (0..n).map(probe).collect() };
    let mut batch = ProbeBatch {
        receivers: Vec::with_capacity(traced.len()),
        pixels: Vec::with_capacity(traced.len()),
        weights: Vec::with_capacity(traced.len()),
        cell: density.cell(),
        rays: n,
        stats: RayStats::default(),
    };
    for (r, st) in traced {
        batch.stats += st;
        if let Some((r, p, pixel, w)) = r {
            batch.receivers.push((r, p));
            batch.pixels.push(pixel);
            batch.weights.push(w);
        }
    }
    batch
}

/// A VPL location's probe sums: estimates of Σ y and Σ y² over its probes (y the probe's
/// visible response times its balance weight), the probes traced, estimates of the probes that
/// see it and of the weighted count (whose mean over the probes traced is the share of the
/// image's pixels that see it), and the pixel rectangle of the probes whose shadow ray found
/// it visible (widened by a probe cell each side; `[u32::MAX, u32::MAX, 0, 0]` while none did).
#[derive(Clone, Copy, Debug)]
struct ProbeSums {
    sum: f64,
    sum2: f64,
    rays_used: usize,
    hits: f64,
    area: f64,
    rect: [u32; 4],
}

impl Default for ProbeSums {
    fn default() -> Self {
        ProbeSums { sum: 0.0, sum2: 0.0, rays_used: 0, hits: 0.0, area: 0.0, rect: [u32::MAX, u32::MAX, 0, 0] }
    }
}

/// One shadow ray of the normalisation, from a probe to a VPL, and what it adds to the VPL's
/// [`ProbeSums`] when it is not blocked: `sum` to Σ y, `sum2` to Σ y², `hits` to the probes
/// that see the VPL.
#[derive(Clone, Copy, Debug, Default)]
struct VisibilitySample {
    lane: u32,
    probe: u32,
    sum: f64,
    sum2: f64,
    hits: f64,
}

/// Chooses which of a VPL's lit probes get a shadow ray, and with which weights
/// ([`VisibilitySample`], lane unset), calling `trace(probe, sample)` in probe order. `lit`
/// holds the probes with a nonzero unshadowed response u, in probe order.
///
/// With at most `n` of them, each is traced with its own response (`sum` u, `sum2` u²,
/// `hits` 1): Σ u·V exactly, V the visibility. Otherwise n visibility samples are placed ∝ u
/// by systematic sampling (offset `xi` ∈ [0, 1) times U/n, U = Σ u, then every U/n along the
/// running sum of u): each sample picks probe i with probability u_i / U, so a probe picked q
/// times and visible adds q·U/n to the estimate of Σ u·V (`sum`), q·(U/n)·u to that of Σ u²·V
/// (`sum2`) and q·U/(n u) to that of the visible probes (`hits`), each unbiased; the samples
/// follow the probes' order, so they are spread over the image as the probes are. A VPL lit
/// by many probes, most of which see it, then needs n rays instead of one per probe: the
/// unshadowed response, which carries most of the spread of y between probes, is summed
/// exactly, and only the visible fraction is sampled.
fn visibility_samples(lit: &[(u32, f32)], n: usize, xi: f64, mut trace: impl FnMut(u32, VisibilitySample)) {
    if lit.len() <= n {
        for &(i, u) in lit {
            let u = u as f64;
            trace(i, VisibilitySample { lane: 0, probe: i, sum: u, sum2: u * u, hits: 1.0 });
        }
        return;
    }
    let total: f64 = lit.iter().map(|&(_, u)| u as f64).sum();
    let step = total / n as f64;
    let (mut taken, mut run, mut next) = (0usize, 0.0f64, xi * step);
    let last = lit.len() - 1;
    for (k, &(i, u)) in lit.iter().enumerate() {
        run += u as f64;
        // Positions (t + xi)·U/n below the running sum fall on this probe; the last probe takes
        // what rounding left (position n − 1 is below U in exact arithmetic).
        let mut q = 0usize;
        while taken < n && (next < run || k == last) {
            q += 1;
            taken += 1;
            next = (taken as f64 + xi) * step;
        }
        if q > 0 {
            let (q, u) = (q as f64, u as f64);
            trace(i, VisibilitySample { lane: 0, probe: i, sum: q * step, sum2: q * step * u, hits: q * step / u });
        }
    }
}

impl ProbeSums {
    /// Adds an unblocked visibility sample; its probe lies at `pixel` with balance weight
    /// `weight`, in probe cells of `cell` pixels.
    fn add(&mut self, v: VisibilitySample, pixel: [u32; 2], weight: f32, cell: [u32; 2]) {
        self.sum += v.sum;
        self.sum2 += v.sum2;
        self.hits += v.hits;
        self.area += v.hits * weight as f64;
        let r = &mut self.rect;
        r[0] = r[0].min(pixel[0].saturating_sub(cell[0]));
        r[1] = r[1].min(pixel[1].saturating_sub(cell[1]));
        r[2] = r[2].max(pixel[0] + cell[0]);
        r[3] = r[3].max(pixel[1] + cell[1]);
    }

    /// The VPL `vpl` (location `group`, `k` chain states, power `p_i`) with its radiance scaled
    /// by P_i / P'_i (module doc); None when no probe saw it or P_i is not finite.
    fn scaled(&self, vpl: Vpl, group: u32, k: u64, p_i: f64, npix: f64) -> Option<Vpl> {
        let kk = self.rays_used.max(1) as f64;
        let mean = self.sum / kk;
        let response = mean * npix;
        if !(response > 0.0) || !p_i.is_finite() {
            return None;
        }
        // 1/P' with its second-order bias removed: E[1/X] ≈ 1/μ + σ²/μ³ for the estimate X of
        // μ, so 1/X − σ̂²/X³ (σ̂² the variance of the mean), never below ½/X.
        let var_mean = ((self.sum2 / kk - mean * mean).max(0.0) / kk) * npix * npix;
        let inv = (1.0 / response) * (1.0 - var_mean / (response * response)).max(0.5);
        let mut v = vpl;
        v.radiance *= (p_i * inv) as f32;
        v.count = k as u32;
        v.group = group;
        Some(v)
    }
}

/// One batch of camera probes.
struct ProbeBatch {
    /// The probes that found a receiver, prepared as the gather prepares its pixels.
    receivers: Vec<(Receiver, Prepared)>,
    /// The pixel of each of them.
    pixels: Vec<[u32; 2]>,
    /// The balance weight of each of them ([`ProbeDensity::weight`]).
    weights: Vec<f32>,
    /// The uniform probes' stratification cell, in pixels.
    cell: [u32; 2],
    /// Camera rays traced (the denominator of the batch's mean).
    rays: usize,
    /// Rays traced building the batch.
    stats: RayStats,
}

impl<K: MutationKernel> Mir<K> {
    fn light_choice(&mut self, scene: &Scene, accel: &Accel, camera: &Camera, stats: &mut RayStats) -> Distribution1D {
        if !self.settings.light_cdf {
            return scene.lights.distribution.clone();
        }
        if let Some((c, d)) = &self.cdf
            && c == camera
        {
            return d.clone();
        }
        let d = light_cdf(scene, accel, camera, 1024, 32, self.settings.max_light, 0x0cdf, stats);
        self.cdf = Some((camera.clone(), d.clone()));
        d
    }

    /// Runs the chain and returns the normalised VPL set (see the module doc).
    pub fn run(
        &mut self,
        scene: &Scene,
        accel: &Accel,
        camera: &Camera,
        m: usize,
        seed: u64,
    ) -> (VplSet, SamplerStats) {
        let t0 = Instant::now();
        let mut rays = RayStats::default();
        let dist = self.light_choice(scene, accel, camera, &mut rays);
        let guide = self.guide.take().filter(|_| self.settings.guided_probes > 0.0);
        let ctx = Context {
            scene,
            accel,
            camera,
            light_choice: &dist,
            max_light: self.settings.max_light.max(1),
            screen: guide.as_ref(),
        };
        let mut report = ChainReport::default();
        let chains = self.settings.chains.clamp(1, m.max(1));
        let n_min = self.settings.pc_samples.max(1);
        let n_pc = self.pc_next.clamp(n_min, 4 * n_min);
        let (pc, fresh, rel_se) = estimate_pc_picks(&self.kernel, &ctx, n_pc, chains, seed, &mut rays);
        report.pc = pc;
        report.pc_samples = n_pc;
        report.pc_error = rel_se;
        // The sample count the next run needs for the target error (1/√N).
        let target = self.settings.pc_target_error.max(1e-6);
        self.pc_next =
            (n_pc as f64 * (rel_se / target).powi(2)).ceil().clamp(n_min as f64, 4.0 * n_min as f64) as usize;
        // Continue the previous chains unless the camera jumped; re-evaluate them for this
        // camera. A chain without a state starts from a fresh pick.
        let mut carried: Vec<Option<PathState>> = if self.jumped || !self.settings.carry {
            Vec::new()
        } else {
            std::mem::take(&mut self.states).iter().map(|x| self.kernel.reevaluate(&ctx, x, &mut rays)).collect()
        };
        carried.resize(chains, None);
        let mut fresh = fresh.into_iter();
        let starts: Vec<PathState> =
            carried.into_iter().take(chains).filter_map(|c| c.or_else(|| fresh.next())).collect();
        if starts.is_empty() {
            report.dark = true;
            self.states.clear();
            self.last = report;
            let warnings = vec![format!(
                "no light reaches what the camera sees through any path the chain samples (P_c = 0 from {} samples): the image shows only emitters seen directly",
                n_pc
            )];
            return (VplSet::default(), SamplerStats { time: t0.elapsed(), rays, warnings, ..Default::default() });
        }
        self.jumped = false;
        // The chains, each grouping its consecutive states by VPL location. Fixed number of
        // states (see `StopRule`): from the rate at which earlier runs moved to new locations,
        // decided before this run starts. The first run of a sampler has no measured rate yet:
        // it stops at m locations.
        let stop = if self.runs == 0 { StopRule::Locations } else { self.settings.stop };
        let count = starts.len();
        let rate = self.move_rate.clamp(1e-3, 1.0);
        let (kernel, chain, steps) = (&self.kernel, self.settings.chain, self.settings.max_steps_per_vpl.max(1));
        let runs: Vec<ChainRun> = starts
            .into_par_iter()
            .enumerate()
            .map(|(c, x)| {
                let share = m / count + (c < m % count) as usize;
                let max_states = (steps * share.max(1)) as u64;
                let fixed_states = match stop {
                    StopRule::States => ((share as f64 / rate).ceil() as u64).clamp(share as u64, max_states),
                    StopRule::Locations => max_states,
                };
                // Chain 0 keeps the stream a single chain had.
                let rng = if c == 0 {
                    Pcg32::from_words(&[seed, TAG_CHAIN])
                } else {
                    Pcg32::from_words(&[seed, TAG_CHAIN, c as u64])
                };
                run_chain(kernel, &ctx, chain, x, share, stop, fixed_states, max_states, rng)
            })
            .collect();
        let (mut proposed, mut accepted) = (0u64, 0u64);
        let mut locations: Vec<(PathState, u64)> = Vec::with_capacity(m);
        let mut rasters = Vec::new();
        for run in runs {
            rasters.extend(run.rasters);
            proposed += run.proposed;
            accepted += run.accepted;
            rays += run.rays;
            report.truncated |= run.truncated;
            locations.extend(run.locations);
            self.states.push(run.last);
        }
        let n_states: u64 = locations.iter().map(|l| l.1).sum();
        let rate = locations.len() as f64 / n_states.max(1) as f64;
        self.move_rate = if self.runs == 0 { rate } else { 0.8 * self.move_rate + 0.2 * rate };
        self.runs += 1;
        report.states = n_states;
        report.locations = locations.len();
        // Normalisation: each location's camera response from probe batches (module doc).
        // Each batch has its own seed, so the result does not depend on which thread traces it.
        // The first batch is traced in parallel up front; most VPLs are seen by enough of its
        // probes. Later batches are traced when a VPL first needs them, serially inside the
        // parallel loop (a parallel initialiser could steal a task that asks for the same batch
        // and re-enter its own initialisation).
        let batches = self.settings.probe_batches.max(1);
        let batch_seed = |b: usize| seed ^ (b as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        let next_guide = ScreenGuide::new(camera, &rasters);
        let density = ProbeDensity::new(camera, self.settings.probes, self.settings.guided_probes, next_guide.clone());
        let probe_sets: Vec<OnceLock<ProbeBatch>> = (0..batches).map(|_| OnceLock::new()).collect();
        let _ = probe_sets[0].set(probes(&ctx, &density, batch_seed(0), true));
        let batch = |b: usize| probe_sets[b].get_or_init(|| probes(&ctx, &density, batch_seed(b), false));
        let npix = camera.pixel_count() as f64;
        let nl = scene.lights.list.len();
        report.power_by_light = vec![0.0; nl];
        let min_hits = self.settings.min_probe_hits;
        let vis_samples = self.settings.visibility_samples.max(1);
        // P' with the chains' own target bound (see `mirpath::TARGET_CLAMP`).
        let g_target = crate::vpl::mirpath::target_g_bound(scene);
        // Each location's probe sums, eight locations per pass over the probes (one VPL per
        // lane of the gather's kernel). A location takes probe batches until enough of its
        // probes see it (or all batches are used); its sums run in probe order, as if it were
        // measured alone.
        let measured: Vec<(Vec<ProbeSums>, RayStats)> = locations
            .par_chunks(8)
            .enumerate()
            .map(|(c, chunk)| {
                let mut st = RayStats::default();
                let mut set = VplSet::default();
                for (s, _) in chunk {
                    set.push(s.vpl);
                }
                let lanes = VplLanes::new(&set);
                let mut sums = vec![ProbeSums::default(); chunk.len()];
                // Neighbouring probes are blocked by the same leaf: a shadow cache per VPL.
                let mut hints = [crate::accel::single::NO_OCCLUDER; 8];
                // Shadow rays set up eight at a time; an unblocked one adds its weights to its
                // VPL's sums (see `VisibilitySample`).
                let mut rays = ShadowBatch::<VisibilitySample>::new();
                // Each lane's probes of the current batch that its VPL lights, unshadowed.
                let mut lit: [Vec<(u32, f32)>; 8] = Default::default();
                let mut active = (1u32 << chunk.len()) - 1;
                for b in 0..batches {
                    if active == 0 {
                        break;
                    }
                    let ProbeBatch { receivers, pixels, weights, cell, rays: count, .. } = batch(b);
                    lit.iter_mut().for_each(Vec::clear);
                    for (i, (r, pt)) in receivers.iter().enumerate() {
                        lanes.each_unshadowed(&set, pt, r, active, g_target, |j, c| {
                            let y = luminance(c) * weights[i];
                            if y > 0.0 {
                                lit[j].push((i as u32, y));
                            }
                        });
                    }
                    let mut add = |v: VisibilitySample| {
                        let i = v.probe as usize;
                        sums[v.lane as usize].add(v, pixels[i], weights[i], *cell)
                    };
                    for j in (0..chunk.len()).filter(|j| active >> j & 1 != 0) {
                        let xi = Pcg32::from_words(&[seed, TAG_VISIBILITY, (8 * c + j) as u64, b as u64]).next_f64();
                        let target = set.position[j];
                        visibility_samples(&lit[j], vis_samples, xi, |i, sample| {
                            let pt = &receivers[i as usize].1;
                            let sample = VisibilitySample { lane: j as u32, ..sample };
                            rays.push(
                                pt.origin_towards(target),
                                target,
                                j as u32,
                                sample,
                                accel,
                                &mut hints,
                                &mut st,
                                &mut add,
                            );
                        });
                    }
                    rays.trace(accel, &mut hints, &mut st, &mut add);
                    let measuring = active;
                    for (j, p) in sums.iter_mut().enumerate().filter(|(j, _)| measuring >> j & 1 != 0) {
                        p.rays_used += count;
                        if p.hits >= min_hits as f64 {
                            active &= !(1 << j);
                        }
                    }
                }
                (sums, st)
            })
            .collect();
        let mut scaled: Vec<Option<Vpl>> = Vec::with_capacity(locations.len());
        let mut footprints: Vec<(f32, [u32; 4])> = Vec::with_capacity(locations.len());
        for (sums, st) in &measured {
            rays += *st;
            for p in sums {
                footprints.push(((p.area / p.rays_used.max(1) as f64) as f32, p.rect));
                let (i, (s, k)) = (scaled.len(), &locations[scaled.len()]);
                scaled.push(p.scaled(s.vpl, i as u32, *k, *k as f64 * pc / n_states as f64, npix));
            }
        }
        for b in probe_sets.iter().filter_map(OnceLock::get) {
            rays += b.stats;
        }
        {
            let mut lum: Vec<f64> = scaled.iter().flatten().map(|v| luminance(v.radiance) as f64).collect();
            if !lum.is_empty() {
                let max = lum.iter().copied().fold(0.0, f64::max);
                let mid = lum.len() / 2;
                let median = *lum.select_nth_unstable_by(mid, f64::total_cmp).1;
                report.max_over_median = if median > 0.0 { max / median } else { 0.0 };
            }
            let lost: u64 = scaled.iter().zip(&locations).filter(|(v, _)| v.is_none()).map(|(_, (_, k))| *k).sum();
            report.dropped = scaled.iter().filter(|v| v.is_none()).count();
            report.dropped_share = lost as f64 / n_states.max(1) as f64;
        }
        let mut set = VplSet::default();
        for ((v, (s, k)), (f, rect)) in scaled.into_iter().zip(&locations).zip(footprints) {
            if let Some(v) = v {
                set.push(v);
                set.footprint.push(f);
                set.footprint_rect.push(rect);
                report.power_by_light[s.source_light() as usize] += *k as f64 * pc / n_states as f64;
            }
        }
        set.groups = locations.len() as u32;
        let mut warnings = Vec::new();
        // A few of many chains stuck at their bound cost a few locations, not worth a warning.
        if report.truncated && report.locations * 10 < m * 9 {
            warnings.push(format!(
                "the chains found only {} of {m} VPL locations within their bound of {} states ({} per VPL): light reaches the camera through very few paths",
                report.locations,
                self.settings.max_steps_per_vpl.max(1) * m.max(1),
                self.settings.max_steps_per_vpl
            ));
        }
        let stats = SamplerStats {
            time: t0.elapsed(),
            candidates: n_states,
            kept: set.len(),
            paths: n_pc as u64,
            accepted,
            proposed,
            rays,
            warnings,
        };
        self.last = report;
        self.guide = next_guide;
        (set, stats)
    }
}

impl<K: MutationKernel> VplSampler for Mir<K> {
    fn name(&self) -> &'static str {
        match self.settings.chain {
            Chain::Mh => "mh",
            Chain::Mtmh(_) => "mtmh",
        }
    }

    fn sample(&mut self, scene: &Scene, accel: &Accel, camera: &Camera, m: usize, seed: u64) -> (VplSet, SamplerStats) {
        self.run(scene, accel, camera, m, seed)
    }

    fn reset(&mut self) {
        self.states.clear();
        self.jumped = true;
        self.guide = None;
        self.pc_next = 0;
    }

    fn camera_moved(&mut self, jumped: bool) {
        if jumped {
            self.jumped = true;
            self.cdf = None;
            self.guide = None;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The estimates `visibility_samples` gives of Σ u·V, Σ u²·V and the visible probes for a
    /// visibility pattern V, as (sum, sum2, hits, rays traced).
    fn sampled(lit: &[(u32, f32)], n: usize, xi: f64, visible: impl Fn(u32) -> bool) -> (f64, f64, f64, usize) {
        let mut e = (0.0, 0.0, 0.0, 0);
        visibility_samples(lit, n, xi, |i, s| {
            e.3 += 1;
            if visible(i) {
                (e.0, e.1, e.2) = (e.0 + s.sum, e.1 + s.sum2, e.2 + s.hits);
            }
        });
        e
    }

    #[test]
    fn visibility_samples_estimate_the_visible_response_without_bias() {
        // 1000 lit probes with responses spread over four decades, seen through a pattern of
        // shadows (runs of hidden probes, as a shadow covers neighbouring probes).
        let mut rng = Pcg32::from_words(&[7]);
        let lit: Vec<(u32, f32)> = (0..1000).map(|i| (3 * i, 10f32.powf(4.0 * rng.next_f32() - 2.0))).collect();
        let visible = |i: u32| (i / 90) % 3 != 1 && !i.is_multiple_of(7);
        let exact = lit.iter().filter(|p| visible(p.0)).fold((0.0, 0.0, 0.0), |a, &(_, u)| {
            let u = u as f64;
            (a.0 + u, a.1 + u * u, a.2 + 1.0)
        });
        // Few probes: each traced once with its own response, so the sums are exact.
        let few = &lit[..200];
        let e = sampled(few, 256, 0.3, visible);
        let exact_few = few.iter().filter(|p| visible(p.0)).map(|p| p.1 as f64).sum::<f64>();
        assert_eq!(e.3, 200);
        assert!((e.0 - exact_few).abs() <= 1e-9 * exact_few);
        // Many probes: 256 samples, at most 256 rays; with every probe visible the estimate of
        // Σ u is exact whatever the offset (the samples' weights sum to U).
        let total: f64 = lit.iter().map(|p| p.1 as f64).sum();
        for xi in [0.0, 0.37, 0.999_999] {
            let e = sampled(&lit, 256, xi, |_| true);
            assert!(e.3 <= 256);
            assert!((e.0 - total).abs() < 1e-9 * total, "{} vs {total}", e.0);
        }
        // Averaged over the offset (a fine grid of it: the estimates are piecewise constant in
        // xi), each estimate equals the exact value: every sample picks a probe ∝ u. Weights
        // u instead of U/n, or offsets not spread over [0, 1), miss by far more than 0.5 %.
        let grid = 20_000;
        let mean = (0..grid)
            .map(|g| sampled(&lit, 256, (g as f64 + 0.5) / grid as f64, visible))
            .fold((0.0, 0.0, 0.0), |a, e| (a.0 + e.0 / grid as f64, a.1 + e.1 / grid as f64, a.2 + e.2 / grid as f64));
        for (m, x, what) in
            [(mean.0, exact.0, "Σ u·V"), (mean.1, exact.1, "Σ u²·V"), (mean.2, exact.2, "visible probes")]
        {
            assert!((m - x).abs() < 5e-3 * x, "{what}: mean {m} against {x}");
        }
        // One offset: the estimate of Σ u·V lies within a few % of it (the samples follow the
        // probes' order, so they cover every shadow run).
        let e = sampled(&lit, 256, 0.5, visible);
        assert!((e.0 - exact.0).abs() < 0.05 * exact.0, "{} vs {}", e.0, exact.0);
    }
}
