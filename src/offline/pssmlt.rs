//! Primary-sample-space Metropolis light transport (`--mode pssmlt`; Kelemen et al. 2002,
//! docs/bibliography.md) over the bidirectional path sampler, multiplexed over strategies
//! (Hachisuka et al. 2014, as in pbrt-v4's `MLTIntegrator`).
//!
//! A state is a vector of uniform numbers u ∈ [0, 1)^∞ read lazily by the path sampler, in three
//! streams (camera sub-path, light sub-path, connection) so that a dimension keeps its meaning
//! when the sub-paths before it change length. Each chain has a fixed path depth d (scattering
//! events); its first camera-stream number picks a strategy s uniformly among the d + 2 of that
//! depth (t = d + 2 − s camera vertices), and the state's value is
//!
//! ```text
//! f_d(u) = (d + 2) · w_{s,t} · C*_{s,t}        at the raster point of the camera path (t ≥ 2)
//!                                                or of the light-tracing splat (t = 1)
//! ```
//!
//! whose expectation over u is the depth-d part of the image, per pixel divided by the pixel
//! count. Over the joint space (d uniform in 0…D, u) the target is I = (D + 1) · lum(f_d(u)).
//!
//! **Normalisation and start-up** (no start-up bias): `bootstrap` independent states, or more
//! where few paths reach the camera ([`bootstrap_size`], fixed by an independent pilot), spread
//! over the depths ([`depth_counts`]) and weighted back, give b = mean I, an unbiased estimate
//! of ∫ I; each chain starts from one of them chosen ∝ I (sampling–importance resampling:
//! (b, state) is then a properly weighted sample of I, and Metropolis–Hastings steps keep it
//! so). The image is `b / spp · Σ_k f(x_k) / I(x_k)` over all chains' states.
//!
//! **Direct part** (`--mlt-direct N`, as `--mode mlt`'s split; by default on when a quick
//! path-traced estimate puts at least [`AUTO_DIRECT_SHARE`] of the light there): the paths of
//! depth 0 and 1 — a light seen directly, direct lighting — are path traced (pt restricted to one or two
//! segments, its MIS between light sampling and BSDF sampling unchanged), N samples a pixel
//! each pass, averaged as pixel samples under the chains' splats; the chains, the bootstrap and
//! b take the depths from 2 up. The image is the sum of two unbiased estimates of disjoint parts
//! of the measurement. It cuts the error where depths 0–1 hold much of the light (Cornell box
//! 45×, glass sphere 2.7×) and raises it where they hold little (thick-walled slit, 1 %: 1.8×,
//! the pass's time lost to the chains), hence the default by share
//! (benches/results/2026-12-07-pssmlt-direct.md).
//!
//! **Mutations**: with probability `large_step` every number is drawn anew (an independent
//! proposal), otherwise each is moved by a normal step of deviation `sigma` per iteration since
//! it was last changed, wrapped around [0, 1) (symmetric: the acceptance is min(1, I′/I)).
//! Numbers are updated lazily, only when the sampler reads them.
//!
//! **Expected values**: each step deposits the proposal with weight a and the current state with
//! 1 − a (Veach 1997 §11.5), so rejected proposals still count.
//!
//! Every chain has its own random streams (seed, chain index), chains run side by side, and their
//! deposits are added to the film in chain order after each pass: the image is the same for a
//! seed at any thread count.

use std::time::Instant;

use crate::progress::Progress;
use glam::{Vec2, Vec3, vec2};
use rayon::prelude::*;

use super::{Budget, OfflineSettings, RenderOutput};
use crate::accel::Accel;
use crate::color::luminance;
use crate::film::{Film, FilmTile};
use crate::path::{Vertex, camera_subpath, camera_subpath_exact, connect, light_subpath, light_subpath_exact};
use crate::sampling::{Pcg32, Sampler};
use crate::scene::Scene;
use crate::stats::RayStats;

/// Stream tags of the bootstrap states, the chains' choice of start, and their mutations.
const TAG_BOOTSTRAP: u64 = 0x5053_4d4c_5442;
const TAG_PILOT: u64 = 0x5053_4d4c_5450;
const TAG_START: u64 = 0x5053_4d4c_5453;
const TAG_CHAIN: u64 = 0x5053_4d4c_5443;
const TAG_SHARE: u64 = 0x5053_4d4c_5348;

/// Streams of the primary sample vector: camera sub-path, light sub-path, connection.
const STREAMS: usize = 3;
const CAMERA_STREAM: usize = 0;
const LIGHT_STREAM: usize = 1;
const CONNECT_STREAM: usize = 2;

/// The chain's settings (pbrt-v4's defaults).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PssmltSettings {
    /// Independent chains.
    pub chains: usize,
    /// Independent states that estimate the normalisation b and from which chains start: at
    /// least this many, more where the pilot finds few paths that reach the camera
    /// ([`bootstrap_size`]).
    pub bootstrap: usize,
    /// Probability of a large step (a fresh, independent state).
    pub large_step: f32,
    /// Standard deviation of a small step per number.
    pub sigma: f32,
    /// Path-traced samples per pixel and pass for the paths of depth 0 and 1 (lights seen
    /// directly and direct lighting), which the chains then leave out; 0: the chains take every
    /// depth; `None`: 1 when a quick path-traced estimate finds at least [`AUTO_DIRECT_SHARE`]
    /// of the light there, else 0.
    pub direct: Option<u32>,
}

/// The share of the light in depths 0–1 from which the direct part is path traced by default.
/// Measured (5.33 s, 256×192, excess nMSE, benches/results/2026-12-07-pssmlt-direct.md): the
/// split cuts the error 45× on the Cornell box (77 % of its light there), 2.7× on the glass
/// sphere (73 %), a little on the box with holes (30 %), and raises it 1.8× on the thick-walled
/// slit (1.1 %), whose chains lose a fifth of their time to it. The threshold picks the better
/// setting on sunlit-room (48 %: on), direct-indirect and left-right (under a fifth: off) too.
pub const AUTO_DIRECT_SHARE: f64 = 0.2;

/// The first path depth the chains take when the direct part is path traced.
pub const FIRST_CHAIN_DEPTH: usize = 2;

impl Default for PssmltSettings {
    fn default() -> Self {
        PssmltSettings { chains: 1000, bootstrap: 100_000, large_step: 0.3, sigma: 0.01, direct: None }
    }
}

impl PssmltSettings {
    /// Rejects absurd values with a message naming the flag.
    pub fn validate(&self) -> Result<(), String> {
        if !(1..=1_000_000).contains(&self.chains) {
            return Err(format!("--mlt-chains {} is outside 1…1000000", self.chains));
        }
        if !(1..=100_000_000).contains(&self.bootstrap) {
            return Err(format!("--bootstrap {} is outside 1…100000000", self.bootstrap));
        }
        if !(self.large_step > 0.0 && self.large_step <= 1.0) {
            return Err(format!("--large-step {} must be in (0, 1]", self.large_step));
        }
        if !(self.sigma > 0.0 && self.sigma <= 1.0) {
            return Err(format!("--sigma {} must be in (0, 1]", self.sigma));
        }
        Ok(())
    }
}

/// What the chains did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PssmltStats {
    /// The normalisation b (mean target luminance over the bootstrap states).
    pub b: f64,
    /// Bootstrap states drawn ([`bootstrap_size`]).
    pub bootstrap_states: u64,
    /// Bootstrap states with a non-zero value.
    pub bootstrap_nonzero: u64,
    /// Large steps proposed and accepted.
    pub large: (u64, u64),
    /// Small steps proposed and accepted.
    pub small: (u64, u64),
    /// Chains that accepted none of their proposals (at least 32 of them): stuck on a state far
    /// brighter than its neighbours, the bright dots MLT renderers are known for.
    pub stuck_chains: u64,
    /// Path-traced samples a pixel and pass of depths 0–1 (0: the chains took every depth).
    pub direct: u32,
    /// The share of the light in depths 0–1 that chose the split (0 when `--mlt-direct` was
    /// given).
    pub direct_share: f64,
}

impl PssmltStats {
    fn add(&mut self, o: &PssmltStats) {
        self.large.0 += o.large.0;
        self.large.1 += o.large.1;
        self.small.0 += o.small.0;
        self.small.1 += o.small.1;
    }

    /// Share of rejected proposals per mutation type: (large, small).
    pub fn rejected(&self) -> (f64, f64) {
        let r = |(p, a): (u64, u64)| if p > 0 { 1.0 - a as f64 / p as f64 } else { 0.0 };
        (r(self.large), r(self.small))
    }
}

/// One number of the state, with the iteration that last changed it and a backup for
/// rejection.
#[derive(Clone, Copy, Debug, Default)]
struct PrimarySample {
    value: f32,
    modified: u64,
    backup: f32,
    modified_backup: u64,
    /// Set before the first read: the initial large step keeps this value (a stratified one).
    preset: bool,
}

/// The Markov chain's state in primary sample space, read through [`Sampler`].
#[derive(Clone, Debug)]
pub struct MltSampler {
    rng: Pcg32,
    x: Vec<PrimarySample>,
    iteration: u64,
    large_step: bool,
    last_large_step: u64,
    sigma: f32,
    p_large: f32,
    stream: usize,
    index: usize,
    /// The second normal number of the last Box–Muller pair, not used yet.
    spare_normal: Option<f32>,
}

/// Largest f32 below 1.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

impl MltSampler {
    /// A state drawn from `rng` at its first reads (iteration 0 is a large step).
    pub fn new(rng: Pcg32, sigma: f32, p_large: f32) -> Self {
        MltSampler {
            rng,
            x: Vec::new(),
            iteration: 0,
            large_step: true,
            last_large_step: 0,
            sigma,
            p_large,
            stream: 0,
            index: 0,
            spare_normal: None,
        }
    }

    /// Begins a proposal: a large step with probability `p_large`, else a small one.
    pub fn start_iteration(&mut self) {
        self.iteration += 1;
        self.large_step = self.rng.next_f32() < self.p_large;
    }

    /// Whether the current proposal is a large step.
    pub fn is_large_step(&self) -> bool {
        self.large_step
    }

    /// Reads from stream `i` from its first number on.
    pub fn start_stream(&mut self, i: usize) {
        debug_assert!(i < STREAMS);
        self.stream = i;
        self.index = 0;
    }

    /// Keeps the proposal.
    pub fn accept(&mut self) {
        if self.large_step {
            self.last_large_step = self.iteration;
        }
    }

    /// Restores the state before the proposal.
    pub fn reject(&mut self) {
        for x in &mut self.x {
            if x.modified == self.iteration {
                x.value = x.backup;
                x.modified = x.modified_backup;
            }
        }
        self.iteration -= 1;
    }

    /// Sets the first value of camera-stream number `k` (before anything is read): the bootstrap
    /// states stratify their first numbers (strategy, raster position).
    pub fn preset_camera(&mut self, k: usize, value: f32) {
        let i = CAMERA_STREAM + STREAMS * k;
        if i >= self.x.len() {
            self.x.resize(i + 1, PrimarySample::default());
        }
        self.x[i] = PrimarySample { value: value.clamp(0.0, ONE_MINUS_EPSILON), preset: true, ..Default::default() };
    }

    /// Replaces the generator of future numbers (a chain started from a bootstrap state
    /// continues with its own streams).
    pub fn reseed(&mut self, rng: Pcg32) {
        self.rng = rng;
    }

    /// Brings number `i` up to the current iteration.
    fn ensure_ready(&mut self, i: usize) {
        if i >= self.x.len() {
            self.x.resize(i + 1, PrimarySample::default());
        }
        let normal = if self.large_step { 0.0 } else { self.standard_normal() };
        let rng = &mut self.rng;
        let x = &mut self.x[i];
        // Not read since the last accepted large step: that step would have drawn it anew.
        if x.modified < self.last_large_step {
            x.value = rng.next_f32();
            x.modified = self.last_large_step;
        }
        x.backup = x.value;
        x.modified_backup = x.modified;
        if x.preset {
            x.preset = false;
        } else if self.large_step {
            x.value = rng.next_f32();
        } else {
            // The small steps it missed, combined: a normal step of σ·√n.
            let n = (self.iteration - x.modified) as f32;
            let step = normal * self.sigma * n.sqrt();
            let v = x.value + step;
            x.value = (v - v.floor()).min(ONE_MINUS_EPSILON);
        }
        x.modified = self.iteration;
    }
}

impl Sampler for MltSampler {
    #[inline]
    fn next_1d(&mut self) -> f32 {
        let i = self.stream + STREAMS * self.index;
        self.index += 1;
        self.ensure_ready(i);
        self.x[i].value
    }
}

impl MltSampler {
    /// A standard normal number: Box–Muller, both numbers of a pair used (the logarithm, square
    /// root and sine/cosine were most of a small step's cost).
    fn standard_normal(&mut self) -> f32 {
        if let Some(z) = self.spare_normal.take() {
            return z;
        }
        let u1 = 1.0 - self.rng.next_f32(); // (0, 1]
        let u2 = self.rng.next_f32();
        let r = (-2.0 * u1.ln()).sqrt();
        let (sin, cos) = (std::f32::consts::TAU * u2).sin_cos();
        self.spare_normal = Some(r * sin);
        r * cos
    }
}

/// A state's value: where on the raster it lands and f_d (see the module doc).
#[derive(Clone, Copy, Debug, Default)]
pub struct Sample {
    /// Raster position.
    pub raster: Vec2,
    /// f_d(u) (zero when the strategy gave nothing).
    pub value: Vec3,
}

/// Scratch sub-paths of one evaluation.
#[derive(Default)]
pub struct Paths {
    camera: Vec<Vertex>,
    light: Vec<Vertex>,
}

/// Evaluates the state of `sampler` for path depth `depth` (f_d, see the module doc). The
/// sub-paths are walked without Russian roulette (the depth is fixed), except with `roulette`
/// (the cheap pilot estimate of the depths' shares).
pub fn evaluate(
    scene: &Scene,
    accel: &Accel,
    sampler: &mut MltSampler,
    depth: usize,
    roulette: bool,
    paths: &mut Paths,
    stats: &mut RayStats,
) -> Sample {
    let cam = &scene.camera;
    sampler.start_stream(CAMERA_STREAM);
    let (s, t, strategies) = if depth == 0 {
        // Only (0, 2): the camera sees a light (s = 1, t = 1 and t = 0 do not exist).
        (0, 2, 1)
    } else {
        let n = depth + 2;
        let s = ((sampler.next_1d() * n as f32) as usize).min(n - 1);
        (s, n - s, n)
    };
    let raster = sampler.next_2d() * vec2(cam.width as f32, cam.height as f32);
    let none = Sample { raster, value: Vec3::ZERO };
    if roulette {
        camera_subpath(scene, accel, raster, sampler, t, &mut paths.camera, stats);
    } else {
        camera_subpath_exact(scene, accel, raster, sampler, t, &mut paths.camera, stats);
    }
    if paths.camera.len() != t {
        return none;
    }
    sampler.start_stream(LIGHT_STREAM);
    if roulette {
        light_subpath(scene, accel, sampler, s, &mut paths.light, stats);
    } else {
        light_subpath_exact(scene, accel, sampler, s, &mut paths.light, stats);
    }
    if paths.light.len() != s {
        return none;
    }
    sampler.start_stream(CONNECT_STREAM);
    let c = connect(scene, accel, &paths.light, &paths.camera, s, t, sampler, stats);
    let value = c.weighted() * strategies as f32;
    if !value.is_finite() || value.min_element() < 0.0 {
        stats.discarded += 1;
        return none;
    }
    Sample { raster: c.raster.unwrap_or(raster), value }
}

/// The chains' target: the value's luminance (zero for nothing).
fn target(v: Vec3) -> f64 {
    let l = luminance(v) as f64;
    if l > 0.0 && l.is_finite() { l } else { 0.0 }
}

/// The target's moments over one depth's pilot states.
#[derive(Clone, Copy, Debug, Default)]
struct Moments {
    sum: f64,
    sum2: f64,
    count: u64,
    nonzero: u64,
}

/// Per depth: the target's moments over a pilot of `n / 4` states, spread over the depths from
/// `first` as [`depth_counts`] spreads states it knows nothing about, each followed to its full
/// depth as the bootstrap follows it (so the pilot's non-zero fraction and spread are the
/// bootstrap's). Spread evenly over the 129 depths of the default `--max-depth` and ended by
/// Russian roulette, the pilot gave each depth 194 states and saw one path in 4000 reach the
/// camera on light-box-thick, where the bootstrap sees one in 150: it found one non-zero state
/// or none, the Neyman half of the bootstrap then followed that one state, and with none the
/// bootstrap kept its smallest size (seed 6: b 40 % low).
fn pilot(
    scene: &Scene,
    accel: &Accel,
    seed: u64,
    n: usize,
    depths: usize,
    first: usize,
    pss: &PssmltSettings,
) -> Vec<Moments> {
    let counts = depth_counts(&vec![Moments::default(); depths], (n / 4).max(depths), first);
    let depth_of: Vec<usize> = counts.iter().enumerate().flat_map(|(d, &k)| std::iter::repeat_n(d, k)).collect();
    let values: Vec<(usize, f64)> = depth_of
        .par_iter()
        .enumerate()
        .map_init(Paths::default, |paths, (i, &d)| {
            let mut st = RayStats::default();
            let mut sampler =
                MltSampler::new(Pcg32::from_words(&[seed, TAG_PILOT, i as u64]), pss.sigma, pss.large_step);
            (d, target(evaluate(scene, accel, &mut sampler, d, false, paths, &mut st).value))
        })
        .collect();
    let mut moments = vec![Moments::default(); depths];
    for (d, w) in values {
        let m = &mut moments[d];
        m.sum += w;
        m.sum2 += w * w;
        m.count += 1;
        m.nonzero += u64::from(w > 0.0);
    }
    moments
}

/// The share of the image's light in the depths below [`FIRST_CHAIN_DEPTH`], estimated by a
/// path tracer on one pixel in four (a full path and a depth-0–1 path from each, on streams of
/// their own), so that the choice of the split is independent of the bootstrap and the chains
/// (each estimator stays unbiased whichever way it goes). 0 when it found no light.
fn direct_share(scene: &Scene, accel: &Accel, seed: u64, max_depth: u32, stats: &mut RayStats) -> f64 {
    let cam = &scene.camera;
    let pixels = cam.pixel_count() as u64;
    let only_direct = super::pt::PathFilter { edges: Some((1, FIRST_CHAIN_DEPTH as u32)), ..Default::default() };
    let direct_depth = max_depth.min(FIRST_CHAIN_DEPTH as u32 - 1);
    let (direct, total, st) = (0..pixels.div_ceil(4))
        .into_par_iter()
        .map(|i| {
            let mut st = RayStats::default();
            let mut sampler = crate::sampling::IndependentSampler::for_stream(seed, TAG_SHARE, i);
            let p = (4 * i + sampler.rng().next_below(4) as u64).min(pixels - 1);
            let mut ray = || {
                let raster =
                    Vec2::new((p % cam.width as u64) as f32, (p / cam.width as u64) as f32) + sampler.next_2d();
                (raster, sampler.next_2d())
            };
            let (r1, l1) = ray();
            let (r2, l2) = ray();
            let full = super::pt::radiance_of_length(
                scene,
                accel,
                cam.generate_ray(r1, l1),
                &mut sampler,
                max_depth,
                &Default::default(),
                &mut st,
            );
            let part = super::pt::radiance_of_length(
                scene,
                accel,
                cam.generate_ray(r2, l2),
                &mut sampler,
                direct_depth,
                &only_direct,
                &mut st,
            );
            (target(part.0), target(full.0), st)
        })
        .reduce(
            || (0.0, 0.0, RayStats::default()),
            |mut a, b| {
                a.2 += b.2;
                (a.0 + b.0, a.1 + b.1, a.2)
            },
        );
    *stats += st;
    if total > 0.0 { (direct / total).min(1.0) } else { 0.0 }
}

/// Pilot states of a depth that must be non-zero before its standard deviation steers the
/// bootstrap: with fewer, the estimate is one or two paths' values, and following it gave one
/// depth half of the bootstrap on the pilot's single hit.
pub const NEYMAN_MIN_NONZERO: u64 = 16;

/// How many bootstrap states each depth gets, `n` in all: half by Neyman's allocation for a
/// cost, in proportion to the pilot's estimate of each depth's standard deviation over the square
/// root of its cost (d + 2 vertices; this minimises the variance of b for the rays spent), among
/// the depths where the pilot found at least [`NEYMAN_MIN_NONZERO`] non-zero states; the other
/// half ∝ 1/(d + 1), so that a depth the pilot missed still gets its share (all of it so when the
/// pilot resolved no depth). At least one state per depth. The allocation changes only the
/// variance of b: each state is weighted by n_total / n_d. Depths below `first` (the direct part,
/// path traced) get none. (A floor ∝ 1/(d + 1)², which spends fewer rays on deep depths, left
/// the glass sphere's rare long paths inside the sphere so few states that b's mean over 8 seeds
/// came out 2.2 % low at z −4.2 in `tests/pssmlt.rs`: a skewed estimate whose spread the seeds
/// under-state.)
fn depth_counts(moments: &[Moments], n: usize, first: usize) -> Vec<usize> {
    let depths = moments.len();
    if first >= depths {
        return vec![0; depths];
    }
    let sigma: Vec<f64> = moments
        .iter()
        .enumerate()
        .map(|(d, m)| {
            if m.nonzero < NEYMAN_MIN_NONZERO {
                return 0.0;
            }
            let k = m.count as f64;
            (m.sum2 / k - (m.sum / k).powi(2)).max(0.0).sqrt() / ((d + 2) as f64).sqrt()
        })
        .collect();
    let sigma_total: f64 = sigma[first..].iter().sum();
    let floor = |d: usize| 1.0 / (d + 1) as f64;
    let floor_total: f64 = (first..depths).map(floor).sum();
    let neyman_share = if sigma_total > 0.0 { 0.5 } else { 0.0 };
    (0..depths)
        .map(|d| {
            if d < first {
                return 0;
            }
            let neyman = if sigma_total > 0.0 { sigma[d] / sigma_total } else { 0.0 };
            let p = neyman_share * neyman + (1.0 - neyman_share) * floor(d) / floor_total;
            ((p * n as f64).round() as usize).max(1)
        })
        .collect()
}

/// Non-zero bootstrap states wanted per chain: so many distinct starts that chains chosen ∝
/// their target rarely share one, and b rests on thousands of paths. 4 rather than 2 since the
/// pilot follows paths to their full depth: measured with a floor ∝ 1/(d + 1)² (since put back
/// to 1/(d + 1), see [`depth_counts`]), the median excess nMSE over 8 seeds at 5.33 s was 7.8 with
/// 2 and 4.7 with 4 on light-box-thick, 0.82 and 0.73 on ajar-door-thick
/// (benches/results/2026-12-07-pssmlt-pilot.md). With the pilot ended by Russian roulette, 4
/// was no better and took more than half of 5.33 s.
pub const BOOTSTRAP_NONZERO_PER_CHAIN: usize = 4;

/// The bootstrap's size: `pss.bootstrap`, or more (up to 16×) so that the states, spread over
/// the depths as [`depth_counts`] spreads them, hold [`BOOTSTRAP_NONZERO_PER_CHAIN`] non-zero
/// states a chain by the pilot's non-zero fraction of each depth. When the pilot found no
/// non-zero state in the chains' depths, the fraction is taken as one over the pilot's states
/// there (it is likely below that): the size is then near its cap, not its floor. The pilot is
/// independent of the bootstrap, so the size is fixed before the bootstrap is drawn and b stays
/// unbiased (a bootstrap that ran until it had found enough would not be). On the box with small
/// holes (light-box-thick) the default 100 000 states held 380 non-zero ones for 1000 chains: b
/// varied by ±20 % over seeds, several chains started from each bright state, and the chains,
/// which accept one large step in 1000 there, stayed where they started. Sized by this rule the
/// median excess nMSE over six seeds at 5.33 s fell from 58 to 13, and on the thick-walled slit
/// from 1.9 to 1.6 (benches/results/2026-12-07-pssmlt-bootstrap.md).
fn bootstrap_size(moments: &[Moments], pss: &PssmltSettings, first: usize) -> usize {
    let shares = depth_counts(moments, pss.bootstrap, first);
    let total: usize = shares.iter().sum();
    if total == 0 {
        return pss.bootstrap;
    }
    let mut fraction: f64 = shares
        .iter()
        .zip(moments)
        .filter(|(_, m)| m.count > 0)
        .map(|(&n, m)| n as f64 / total as f64 * m.nonzero as f64 / m.count as f64)
        .sum();
    if !(fraction > 0.0) {
        let piloted: u64 = moments.iter().skip(first).map(|m| m.count).sum();
        fraction = 1.0 / piloted.max(1) as f64;
    }
    let want = (BOOTSTRAP_NONZERO_PER_CHAIN * pss.chains) as f64;
    let cap = pss.bootstrap.saturating_mul(16).min(100_000_000);
    ((want / fraction).ceil() as usize).clamp(pss.bootstrap, cap.max(pss.bootstrap))
}

/// Stratified first camera-stream numbers of the `count` bootstrap states of one depth: the
/// raster position (numbers `dims − 2`, `dims − 1`) jittered in `count` distinct cells, chosen at
/// random, of a g × g grid (g = ⌈√count⌉), and the strategy number before it (depth > 0) in a
/// Latin hypercube ((π(k) + ξ) / count for a random permutation π). Each state's numbers are
/// still uniform, so b stays unbiased, while a depth's raster positions cover the image evenly
/// (the camera seeing a small light is then measured without the noise of where samples fell).
fn stratified(seed: u64, depth: usize, count: usize, dims: usize) -> Vec<Vec<f32>> {
    let mut rng = Pcg32::from_words(&[seed, TAG_BOOTSTRAP, u64::MAX, depth as u64]);
    let shuffled = |n: usize, rng: &mut Pcg32| {
        let mut perm: Vec<u32> = (0..n as u32).collect();
        for i in (1..n).rev() {
            perm.swap(i, rng.next_below(i as u32 + 1) as usize);
        }
        perm
    };
    let mut out = Vec::with_capacity(dims);
    if dims > 2 {
        let perm = shuffled(count, &mut rng);
        out.push(perm.iter().map(|&p| ((p as f64 + rng.next_f64()) / count as f64) as f32).collect());
    }
    let g = (count as f64).sqrt().ceil().max(1.0) as usize;
    let cells = shuffled(g * g, &mut rng);
    let (mut xs, mut ys) = (Vec::with_capacity(count), Vec::with_capacity(count));
    for &c in &cells[..count] {
        let (cx, cy) = (c as usize % g, c as usize / g);
        xs.push(((cx as f64 + rng.next_f64()) / g as f64) as f32);
        ys.push(((cy as f64 + rng.next_f64()) / g as f64) as f32);
    }
    out.push(xs);
    out.push(ys);
    out
}

/// What a chain adds to the film in a pass: (raster position, value).
type Deposits = Vec<(Vec2, Vec3)>;

/// One chain.
struct Chain {
    sampler: MltSampler,
    accept_rng: Pcg32,
    depth: usize,
    current: Sample,
    current_i: f64,
    paths: Paths,
    /// Proposals made and accepted over the run.
    proposed: u64,
    accepted: u64,
}

/// The bootstrap state `i`'s sampler, its first numbers stratified ([`stratified`]).
fn bootstrap_sampler(seed: u64, i: u64, pss: &PssmltSettings, strata: &Strata) -> MltSampler {
    let mut s = MltSampler::new(Pcg32::from_words(&[seed, TAG_BOOTSTRAP, i]), pss.sigma, pss.large_step);
    let d = strata.depth_of[i as usize] as usize;
    let k = i as usize - strata.first[d];
    for (j, values) in strata.numbers[d].iter().enumerate() {
        s.preset_camera(j, values[k]);
    }
    s
}

/// The bootstrap states' depths and stratified first numbers.
struct Strata {
    /// Depth of each state.
    depth_of: Vec<u32>,
    /// Index of the first state of each depth.
    first: Vec<usize>,
    /// Per depth, per camera number, per state of that depth.
    numbers: Vec<Vec<Vec<f32>>>,
}

/// Renders `scene` with PSSMLT; also returns the chains' statistics.
pub fn render_pssmlt(
    scene: &Scene,
    accel: &Accel,
    settings: &OfflineSettings,
    pss: &PssmltSettings,
    progress: &dyn Progress,
) -> (RenderOutput, PssmltStats) {
    let start = Instant::now();
    let cam = &scene.camera;
    let mut film = Film::new(cam.width, cam.height, settings.filter, false);
    let mut stats = RayStats::default();
    let seed = settings.seed;
    let depths = settings.max_depth as usize + 1;

    // Bootstrap: b and the states chains start from; state i has depth depth_of[i].
    let share =
        if pss.direct.is_none() { direct_share(scene, accel, seed, settings.max_depth, &mut stats) } else { 0.0 };
    let direct = pss.direct.unwrap_or(u32::from(share >= AUTO_DIRECT_SHARE));
    let first_depth = if direct > 0 { FIRST_CHAIN_DEPTH } else { 0 };
    let moments = pilot(scene, accel, seed, pss.bootstrap, depths, first_depth, pss);
    let n_states = bootstrap_size(&moments, pss, first_depth);
    let counts = depth_counts(&moments, n_states, first_depth);
    let n_boot: usize = counts.iter().sum();
    let strata = {
        let depth_of: Vec<u32> =
            counts.iter().enumerate().flat_map(|(d, &k)| std::iter::repeat_n(d as u32, k)).collect();
        let first = counts.iter().scan(0, |acc, &k| Some(std::mem::replace(acc, *acc + k))).collect();
        // Strategy and raster position (depth 0 has only the raster position).
        let numbers =
            (0..depths).into_par_iter().map(|d| stratified(seed, d, counts[d], if d == 0 { 2 } else { 3 })).collect();
        Strata { depth_of, first, numbers }
    };
    let depth_of = &strata.depth_of;
    let boot: Vec<(f64, RayStats)> = (0..n_boot as u64)
        .into_par_iter()
        .map_init(Paths::default, |paths, i| {
            let mut st = RayStats::default();
            let mut sampler = bootstrap_sampler(seed, i, pss, &strata);
            let d = depth_of[i as usize] as usize;
            let s = evaluate(scene, accel, &mut sampler, d, false, paths, &mut st);
            st.samples += 1;
            (target(s.value) * n_boot as f64 / counts[d] as f64, st)
        })
        .collect();
    let mut cdf = Vec::with_capacity(boot.len());
    let mut total = 0.0f64;
    for (w, st) in &boot {
        stats += *st;
        total += w;
        cdf.push(total);
    }
    let mut chain_stats = PssmltStats {
        // No states when the direct part takes every depth (--max-depth 1).
        b: if n_boot > 0 { total / n_boot as f64 } else { 0.0 },
        bootstrap_states: n_boot as u64,
        bootstrap_nonzero: boot.iter().filter(|(w, _)| *w > 0.0).count() as u64,
        ..Default::default()
    };
    drop(boot);
    let b = chain_stats.b;
    let pixels = cam.width as u64 * cam.height as u64;
    // One mutation per pixel per pass.
    let per_pass_spp = 1;
    chain_stats.direct = direct;
    chain_stats.direct_share = share;
    if !(b > 0.0) && direct == 0 {
        // Nothing in the bootstrap reached the camera: the image is black (as pt's would be
        // at that sample count).
        settings.budget.start_progress(progress);
        progress.finish();
        film.add_splat_pass();
        let spp = match settings.budget {
            Budget::Samples(n) => n,
            Budget::Time(_) => 1,
        };
        return (RenderOutput { film, stats, spp, elapsed: start.elapsed() }, chain_stats);
    }

    // Chains, each started from a bootstrap state chosen ∝ its target (none when only the
    // direct part has light).
    let n_chains = if b > 0.0 { pss.chains as u64 } else { 0 };
    let mut chains: Vec<Chain> = (0..n_chains)
        .into_par_iter()
        .map(|c| {
            let mut pick = Pcg32::from_words(&[seed, TAG_START, c]);
            let u = pick.next_f64() * total;
            let i = cdf.partition_point(|&x| x <= u).min(cdf.len() - 1);
            let depth = depth_of[i] as usize;
            let mut sampler = bootstrap_sampler(seed, i as u64, pss, &strata);
            let mut paths = Paths::default();
            let mut st = RayStats::default();
            let current = evaluate(scene, accel, &mut sampler, depth, false, &mut paths, &mut st);
            let current_i = target(current.value);
            debug_assert!(current_i > 0.0, "a bootstrap state chosen ∝ its target has one");
            sampler.reseed(Pcg32::from_words(&[seed, TAG_CHAIN, c, 0]));
            let accept_rng = Pcg32::from_words(&[seed, TAG_CHAIN, c, 1]);
            Chain { sampler, accept_rng, depth, current, current_i, paths, proposed: 0, accepted: 0 }
        })
        .collect();
    drop((cdf, strata));

    let per_chain = |c: usize, n: u64| -> u64 {
        let k = pss.chains as u64;
        n / k + u64::from((c as u64) < n % k)
    };
    // The direct part: path-traced samples of the depths below the chains', `pss.direct` a
    // pixel each pass, averaged as pixel samples under the splats.
    let direct_settings = OfflineSettings { aovs: false, ..settings.clone() };
    let tiles = film.tiles(super::TILE);
    let only_direct = super::pt::PathFilter { edges: Some((1, FIRST_CHAIN_DEPTH as u32)), ..Default::default() };
    let direct_depth = settings.max_depth.min(FIRST_CHAIN_DEPTH as u32 - 1);
    let direct_fn = |raster: Vec2, sampler: &mut crate::sampling::PixelSampler, _: &mut FilmTile, st: &mut RayStats| {
        let ray = cam.generate_ray(raster, sampler.next_2d());
        super::pt::radiance_of_length(scene, accel, ray, sampler, direct_depth, &only_direct, st)
    };
    let spp = settings.budget.drive(start, progress, |pass| {
        if direct > 0 {
            let first = pass * direct;
            stats += super::pixel_pass(scene, &direct_settings, &mut film, &tiles, first..first + direct, &direct_fn);
        }
        let mutations = pixels * per_pass_spp as u64;
        let results: Vec<(Deposits, RayStats, PssmltStats)> = chains
            .par_iter_mut()
            .enumerate()
            .map(|(c, ch)| {
                let n = per_chain(c, mutations);
                let mut deposits = Vec::with_capacity(2 * n as usize);
                let mut st = RayStats::default();
                let mut cs = PssmltStats::default();
                for _ in 0..n {
                    ch.sampler.start_iteration();
                    let large = ch.sampler.is_large_step();
                    let proposal = evaluate(scene, accel, &mut ch.sampler, ch.depth, false, &mut ch.paths, &mut st);
                    st.samples += 1;
                    let pi = target(proposal.value);
                    let a = if ch.current_i > 0.0 { (pi / ch.current_i).min(1.0) } else { 1.0 };
                    // Expected values: the proposal with weight a, the current state with 1 − a,
                    // each as f / I · b.
                    if a > 0.0 {
                        deposits.push((proposal.raster, proposal.value * (a * b / pi) as f32));
                    }
                    if a < 1.0 {
                        let w = (1.0 - a) * b / ch.current_i;
                        deposits.push((ch.current.raster, ch.current.value * w as f32));
                    }
                    let accepted = (ch.accept_rng.next_f64()) < a;
                    let count = if large { &mut cs.large } else { &mut cs.small };
                    count.0 += 1;
                    ch.proposed += 1;
                    if accepted {
                        count.1 += 1;
                        ch.accepted += 1;
                        ch.current = proposal;
                        ch.current_i = pi;
                        ch.sampler.accept();
                    } else {
                        ch.sampler.reject();
                    }
                }
                (deposits, st, cs)
            })
            .collect();
        let mut tile = FilmTile::new(0, 0, 0, 0, false);
        for (deposits, st, cs) in results {
            tile.splats.extend(deposits);
            stats += st;
            chain_stats.add(&cs);
        }
        film.merge_tile(&tile);
        for _ in 0..per_pass_spp {
            film.add_splat_pass();
        }
        per_pass_spp
    });
    chain_stats.stuck_chains = chains.iter().filter(|c| c.proposed >= 32 && c.accepted == 0).count() as u64;
    (RenderOutput { film, stats, spp, elapsed: start.elapsed() }, chain_stats)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bootstrap grows as 1 / (the non-zero fraction the chains' depths would see), from
    /// `--bootstrap` up to 16× it, and never shrinks; depths below `first` do not count.
    #[test]
    fn the_bootstrap_grows_where_few_paths_reach_the_camera() {
        let pss = PssmltSettings { chains: 1000, bootstrap: 100_000, ..Default::default() };
        let depth = |count: u64, nonzero: u64| Moments { sum: nonzero as f64, sum2: nonzero as f64, count, nonzero };
        // Every depth 1 % non-zero: 4000 wanted / 1 % = 400 000.
        let one_percent = vec![depth(1000, 10); 4];
        assert!(bootstrap_size(&one_percent, &pss, 0).abs_diff(400_000) <= 1);
        // Plenty reach the camera: the size given.
        assert_eq!(bootstrap_size(&[depth(1000, 500); 4], &pss, 0), 100_000);
        // Almost none: capped at 16×. None at all in 4000 pilot states: taken as 1 in 4000, so
        // 8 000 000, capped (it was the size given, the floor, which left light-box-thick's
        // seeds 6 and 7 with 100 000 states and b 40 % low on seed 6).
        assert_eq!(bootstrap_size(&[depth(100_000, 1); 4], &pss, 0), 1_600_000);
        assert_eq!(bootstrap_size(&[depth(1000, 0); 4], &pss, 0), 1_600_000);
        // A bright direct part (depths 0-1) path traced apart does not count.
        let mut split = one_percent.clone();
        split[0] = depth(1000, 1000);
        split[1] = depth(1000, 1000);
        // (Within one state: the shares' sum rounds.)
        assert!(bootstrap_size(&split, &pss, 2).abs_diff(400_000) <= 1);
        assert!(bootstrap_size(&split, &pss, 0) < 400_000);
    }

    /// A depth steers the Neyman half only when the pilot found enough non-zero states there:
    /// one hit among 194 (light-box-thick's pilot when it was spread evenly) leaves the
    /// allocation ∝ 1/(d + 1); sixteen give that depth the Neyman half.
    #[test]
    fn one_pilot_hit_does_not_steer_the_bootstrap() {
        let hits = |nonzero: u64| Moments { sum: nonzero as f64, sum2: nonzero as f64 * 100.0, count: 194, nonzero };
        let mut moments = vec![hits(0); 6];
        let harmonic = depth_counts(&moments, 10_000, 2);
        moments[3] = hits(1);
        assert_eq!(depth_counts(&moments, 10_000, 2), harmonic);
        assert_eq!(&harmonic[..2], &[0, 0]);
        assert!(harmonic.windows(2).skip(2).all(|w| w[0] > w[1]), "{harmonic:?}");
        moments[3] = hits(16);
        let steered = depth_counts(&moments, 10_000, 2);
        assert!(steered[3] > 5000 && steered[3] < 5000 + harmonic[3] + 2, "{steered:?}");
    }

    /// The state's first `n` numbers of each stream, without a step.
    fn peek(s: &MltSampler, n: usize) -> Vec<f32> {
        (0..STREAMS).flat_map(|stream| (0..n).map(move |k| s.x[stream + STREAMS * k].value)).collect()
    }

    /// Reads the first `n` numbers of each stream, as an evaluation does once per iteration.
    fn read(s: &mut MltSampler, n: usize) -> Vec<f32> {
        let mut v = Vec::new();
        for stream in 0..STREAMS {
            s.start_stream(stream);
            v.extend((0..n).map(|_| s.next_1d()));
        }
        v
    }

    /// A rejected proposal leaves the state exactly as before it (also for numbers first read
    /// by the proposal), an accepted large step replaces every number, and small steps move each
    /// number by about σ (wrapped into [0, 1)).
    #[test]
    fn rejection_restores_the_state_and_steps_have_their_size() {
        let mut s = MltSampler::new(Pcg32::new(3), 0.01, 0.3);
        let x0 = read(&mut s, 4);
        assert!(x0.iter().all(|&v| (0.0..1.0).contains(&v)));
        let mut moved = Vec::new();
        for _ in 0..2000 {
            s.start_iteration();
            let large = s.is_large_step();
            let y = read(&mut s, 4);
            assert!(y.iter().all(|&v| (0.0..1.0).contains(&v)));
            if !large {
                for (a, b) in x0.iter().zip(&y) {
                    let d = (b - a).abs();
                    moved.push(d.min(1.0 - d) as f64);
                }
            }
            s.reject();
            assert_eq!(peek(&s, 4), x0, "rejection restores the state");
        }
        // |N(0, σ²)| has mean σ·√(2/π).
        let mean = moved.iter().sum::<f64>() / moved.len() as f64;
        assert!((mean / (0.01 * (2.0 / std::f64::consts::PI).sqrt()) - 1.0).abs() < 0.1, "{mean}");
        loop {
            s.start_iteration();
            if s.is_large_step() {
                break;
            }
            s.reject();
        }
        let y = read(&mut s, 4);
        s.accept();
        assert!(y.iter().zip(&x0).all(|(a, b)| a != b));
        assert_eq!(peek(&s, 4), y);
    }
}
