//! Path-space Metropolis light transport (`--mode mlt`; Veach & Guibas 1997, Veach 1997 ch. 11,
//! with the formulation of Fischer and of Cline & Egbert, docs/bibliography.md).
//!
//! The chains walk over complete paths ȳ = y_0 … y_{k−1} ([`path`]), with target f_lum(ȳ), the
//! luminance of the measurement contribution, and the mutations of [`mutation`], [`perturb`]
//! and [`subpath`]: the bidirectional mutation (`--bidir-share`, ⅔ of the proposals when
//! others are on), and the lens, caustic and multi-chain perturbations and the lens sub-path
//! mutation with its rover (the rest, shared equally among those that apply to the path:
//! [`MltSettings::choose`]). The bidirectional mutation's probability does not depend on the
//! state, and each other type's share depends only on the path's length and which vertices are
//! specular, which its proposals keep, so each type keeps detailed balance on its own
//! (Fischer §3.5.4); when none applies the state stays for that step.
//! Selectable with `--mutations`.
//!
//! **Normalisation and start-up** (no start-up bias; Veach 1997 §11.3): `bootstrap` independent
//! bidirectional samples, each a light and a camera walk with a fixed continuation probability
//! (1 up to [`RR_FROM`] vertices, then [`RR_KEEP`]) and every connection of their prefixes, each
//! connected path weighted by the balance heuristic over all the strategies that could have
//! made it: `W = 1 / Σ_j R_L(j) R_E(k−j) / lum C*_j` (R: the walks' probability of reaching
//! that many vertices). b = mean of Σ W per sample is an unbiased estimate of ∫ f_lum; each
//! chain starts from one connected path chosen ∝ W (sampling–importance resampling), so
//! (b, start) is properly weighted and no warm-up is discarded. The raster positions of the
//! bootstrap samples are stratified over the pixels (sample i in pixel (i + o) mod P for a random
//! offset o, so each stays uniform).
//!
//! **Image**: each step deposits b · f/f_lum of the proposal with weight a and of the current
//! state with 1 − a (expected values, Veach 1997 §11.5), one mutation per pixel per pass, so the
//! image is `b / passes · Σ f/f_lum`, the scale of the other modes (plus the direct part below).
//!
//! **Direct part** (`--mlt-direct N`, default 1; Mitsuba's split of direct illumination off the
//! chains, extended): the paths [`in_direct_part`] names — a light, or a surface it lights
//! directly, seen directly or through mirrors and glass, and the paths no connection can make
//! (caustics seen through glass) — are left to the path tracer restricted to them
//! ([`super::pt::PathFilter::mlt_direct_part`]: emitters hit after delta bounces, next-event
//! estimation at the first non-delta vertex, its MIS unchanged), N samples a pixel each pass,
//! averaged as pixel samples under the chains' splats. The chains' target is f_lum on the other
//! paths (a proposal in the direct part has target 0 and is rejected), the bootstrap counts only
//! those, and b is their brightness. The image is the sum of two unbiased estimates of disjoint
//! parts of the measurement; the chains no longer spend most of their mutations on the lamp and
//! the directly lit walls, which dominate f_lum in a room lit by a ceiling lamp (256×192, 16 s,
//! excess nMSE: glass-sphere 0.91 → 0.38, light-box-thick 7.2 → 1.9, with paths of ≤ 3 vertices
//! as the direct part), nor get stuck on paths that no mutation can move (glass-sphere
//! at 5.33 s: see benches/results/2026-12-07-mlt-direct.md).
//! `--mlt-direct 0` gives every path to the chains. The image mean is exactly the direct part's
//! plus b (every step deposits luminance b in total), so a test of the mean tests b.
//!
//! Every chain has its own random stream (seed, chain), chains run side by side, and deposits
//! enter the film in chain order: the image is the same for a seed at any thread count.
//!
//! Lights at infinity (sun, sky) are not path vertices here: [`supported`] says so before a
//! render (use `--mode pssmlt` or `bdpt` for them).

pub mod mutation;
pub mod path;
pub mod perturb;
pub mod subpath;

use std::time::Instant;

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::{Budget, OfflineSettings, RenderOutput};
use crate::accel::Accel;
use crate::bsdf::TransportMode;
use crate::color::luminance;
use crate::film::{Film, FilmTile};
use crate::progress::Progress;
use crate::sampling::{Pcg32, PixelSampler, Sampler};
use crate::scene::Scene;
use crate::stats::RayStats;
use mutation::{Bidirectional, Context, Mutation, State};
use path::{PathVertex, WalkPair, extend, sample_light_vertex, trace, visible};
use perturb::{CausticPerturbation, LensPerturbation, MultiChainPerturbation};
use subpath::{LensSubpath, Rover};

/// Stream tags: bootstrap samples, the bootstrap's pixel offset, chains' starts, chains.
const TAG_BOOTSTRAP: u64 = 0x4d4c_5442_4f4f;
const TAG_OFFSET: u64 = 0x4d4c_544f_4646;
const TAG_START: u64 = 0x4d4c_5453_5452;
const TAG_CHAIN: u64 = 0x4d4c_5443_484e;

/// Bootstrap walks continue with probability 1 until they have this many vertices…
pub const RR_FROM: usize = 4;
/// …and with this probability after that.
pub const RR_KEEP: f64 = 0.8;

/// The mutation types.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MutationKind {
    /// Bidirectional mutation.
    Bidir,
    /// Lens perturbation.
    Lens,
    /// Caustic perturbation.
    Caustic,
    /// Multi-chain perturbation.
    MultiChain,
    /// Lens sub-path mutation (with the rover).
    Subpath,
}

impl MutationKind {
    /// All types, in the order of the statistics.
    pub const ALL: [MutationKind; 5] = [
        MutationKind::Bidir,
        MutationKind::Lens,
        MutationKind::Caustic,
        MutationKind::MultiChain,
        MutationKind::Subpath,
    ];

    /// The types in use by default (`--mutations`): all but the lens sub-path mutation, which
    /// at its share cost accuracy on the slit and the glass sphere and helped the box with holes
    /// only within the seeds' spread (benches/results/2026-12-07-mlt-mutations.md).
    pub const DEFAULT: [MutationKind; 4] =
        [MutationKind::Bidir, MutationKind::Lens, MutationKind::Caustic, MutationKind::MultiChain];

    /// Flag name.
    pub fn name(self) -> &'static str {
        match self {
            MutationKind::Bidir => "bidir",
            MutationKind::Lens => "lens",
            MutationKind::Caustic => "caustic",
            MutationKind::MultiChain => "multichain",
            MutationKind::Subpath => "subpath",
        }
    }

    /// The mutation itself.
    pub fn mutation(self) -> &'static dyn Mutation {
        match self {
            MutationKind::Bidir => &Bidirectional,
            MutationKind::Lens => &LensPerturbation,
            MutationKind::Caustic => &CausticPerturbation,
            MutationKind::MultiChain => &MultiChainPerturbation,
            MutationKind::Subpath => &LensSubpath,
        }
    }

    /// Parses a comma-separated list ("bidir,lens,caustic,multichain,subpath").
    pub fn parse_list(s: &str) -> Result<Vec<MutationKind>, String> {
        let mut out = Vec::new();
        for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let k = MutationKind::ALL.into_iter().find(|k| k.name() == part).ok_or_else(|| {
                format!("--mutations: unknown mutation '{part}' (bidir, lens, caustic, multichain, subpath)")
            })?;
            if !out.contains(&k) {
                out.push(k);
            }
        }
        if out.is_empty() {
            return Err("--mutations: name at least one of bidir, lens, caustic, multichain, subpath".into());
        }
        Ok(out)
    }
}

/// The chains' settings.
#[derive(Clone, Debug, PartialEq)]
pub struct MltSettings {
    /// Independent chains.
    pub chains: usize,
    /// Bidirectional samples that estimate b and from which chains start.
    pub bootstrap: usize,
    /// Mutation types in use.
    pub mutations: Vec<MutationKind>,
    /// Path-traced samples per pixel and pass for the direct part ([`in_direct_part`]: lights
    /// and directly lit surfaces, seen directly or through specular surfaces, and the paths no
    /// connection can make), which the chains then leave out; 0: the chains take every path.
    pub direct: u32,
    /// Probability of the bidirectional mutation when other types are in use too (⅔: at 16 s,
    /// 3 seeds, it beat ½ and 0.8 on the slit and the box with holes, and tied on the glass
    /// sphere; benches/results/2026-12-07-mlt-mutations.md).
    pub bidir_share: f64,
}

/// Whether a path of `k` vertices y_0 (light) … y_{k−1} (lens) is in the direct part, whose
/// y_i is specular when `specular(i)`:
/// - every vertex between the lens and y_1 is specular: a light seen directly (k = 2) or a
///   surface it lights (k = 3), either of them also seen through mirrors and glass; or
/// - no edge of the path can be a connection (y_1 and y_{k−2} specular, and no two
///   non-specular vertices adjacent): a caustic seen in a mirror or through glass (L S D S E),
///   which only a camera walk reaching the light makes. No mutation moves such a path (every
///   perturbation and the bidirectional mutation join two non-specular vertices), so the few
///   chains that start on one keep its pixel for the whole render (on the glass sphere, bootstrap
///   samples of 0.5–1 % of b each, 5–11 chains on one pixel).
///
/// The path tracer finds the first kind by hitting the light after delta bounces or by
/// next-event estimation at the first non-delta vertex, the second by hitting the light after
/// a delta bounce, with its own weights (`pt::PathFilter::mlt_direct_part`).
pub fn in_direct_part(k: usize, specular: impl Fn(usize) -> bool) -> bool {
    if (2..k.saturating_sub(1)).all(&specular) {
        return true;
    }
    specular(1) && specular(k - 2) && (1..k - 2).all(|i| specular(i) || specular(i + 1))
}

impl Default for MltSettings {
    fn default() -> Self {
        MltSettings {
            chains: 1000,
            bootstrap: 100_000,
            mutations: MutationKind::DEFAULT.to_vec(),
            direct: 1,
            bidir_share: 2.0 / 3.0,
        }
    }
}

impl MltSettings {
    /// Whether the chains take the path of `k` vertices whose y_i is specular when
    /// `specular(i)`: every path of at least two vertices when the direct part is off, else
    /// those outside it.
    pub fn chains_take(&self, k: usize, specular: impl Fn(usize) -> bool) -> bool {
        k >= 2 && (self.direct == 0 || !in_direct_part(k, specular))
    }

    /// The type of the next proposal from `x`, for a uniform `u` ∈ [0, 1): the bidirectional
    /// mutation with probability `bidir_share` (1 when it is the only type in use, whatever x
    /// is), the perturbations in use that apply to x ([`Mutation::applies`]) the rest in equal
    /// shares;
    /// `None` when none of them applies (the state stays for that step). A perturbation's share
    /// depends only on what its proposals keep (length, specular vertices), so it is the same at
    /// both ends of each of its moves.
    pub fn choose(&self, x: &State, u: f64) -> Option<MutationKind> {
        let bidir = self.mutations.contains(&MutationKind::Bidir);
        let perturbations = || self.mutations.iter().copied().filter(|&k| k != MutationKind::Bidir);
        let p_bidir = match (bidir, perturbations().next().is_some()) {
            (false, _) => 0.0,
            (true, false) => return Some(MutationKind::Bidir),
            (true, true) => self.bidir_share,
        };
        if u < p_bidir {
            return Some(MutationKind::Bidir);
        }
        let n = perturbations().filter(|k| k.mutation().applies(x)).count();
        let v = (u - p_bidir) / (1.0 - p_bidir);
        let i = ((v * n as f64) as usize).min(n.checked_sub(1)?);
        perturbations().filter(|k| k.mutation().applies(x)).nth(i)
    }
}

/// Per mutation type: proposals, those that gave a path, accepted.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MutationCounts {
    /// Proposals of this type.
    pub proposed: u64,
    /// Proposals that gave a path with a contribution (the rest did not apply or failed).
    pub made: u64,
    /// Accepted proposals.
    pub accepted: u64,
}

/// What the chains did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MltStats {
    /// The normalisation b.
    pub b: f64,
    /// Bootstrap samples with a non-zero weight.
    pub bootstrap_nonzero: u64,
    /// Per type, in [`MutationKind::ALL`]'s order.
    pub counts: [MutationCounts; MutationKind::ALL.len()],
    /// Chains that accepted none of their proposals (at least 32 of them).
    pub stuck_chains: u64,
    /// Sum over steps of the current path's vertex count (mean path length = this / steps).
    pub vertex_steps: u64,
    /// Steps on which no mutation in use applied to the state (it stayed).
    pub idle_steps: u64,
}

impl MltStats {
    /// The chains' steps: proposals and idle steps.
    pub fn steps(&self) -> u64 {
        self.counts.iter().map(|c| c.proposed).sum::<u64>() + self.idle_steps
    }

    /// Mean vertex count of the chains' states over their steps.
    pub fn mean_path(&self) -> f64 {
        self.vertex_steps as f64 / self.steps().max(1) as f64
    }

    /// Share of the steps on which no mutation in use applied.
    pub fn idle_fraction(&self) -> f64 {
        self.idle_steps as f64 / self.steps().max(1) as f64
    }

    /// Accepted over proposed, all types together.
    pub fn acceptance(&self) -> Option<f64> {
        let p: u64 = self.counts.iter().map(|c| c.proposed).sum();
        let a: u64 = self.counts.iter().map(|c| c.accepted).sum();
        (p > 0).then(|| a as f64 / p as f64)
    }
}

/// Why a scene cannot be rendered with `mlt`, if it cannot.
pub fn supported(scene: &Scene) -> Result<(), String> {
    if scene.lights.list.iter().any(|l| l.at_infinity()) {
        return Err("--mode mlt does not handle lights at infinity (sun, sky) yet: use --mode pssmlt or bdpt".into());
    }
    Ok(())
}

/// Probability that a bootstrap walk reaches `v` vertices.
fn reach(v: usize) -> f64 {
    /// `RR_KEEP.powi(i)` for the lengths walks reach in practice.
    static POWERS: std::sync::LazyLock<[f64; 256]> =
        std::sync::LazyLock::new(|| std::array::from_fn(|i| RR_KEEP.powi(i as i32)));
    match v.saturating_sub(RR_FROM) {
        0 => 1.0,
        i if i < 256 => POWERS[i],
        i => RR_KEEP.powi(i.min(i32::MAX as usize) as i32),
    }
}

/// One bootstrap sample's walks (deterministic in (seed, i, offset)).
fn bootstrap_walks(
    scene: &Scene,
    accel: &Accel,
    seed: u64,
    i: u64,
    offset: u64,
    max_vertices: usize,
    stats: &mut RayStats,
) -> (Vec<PathVertex>, Vec<PathVertex>) {
    let mut rng = Pcg32::from_words(&[seed, TAG_BOOTSTRAP, i]);
    let cam = &scene.camera;
    let mut light = Vec::new();
    if let Some(v) = sample_light_vertex(scene, &mut rng) {
        light.push(v);
        while light.len() < max_vertices - 1 {
            if light.len() >= RR_FROM && rng.next_f64() >= RR_KEEP {
                break;
            }
            if !extend(scene, accel, &mut rng, &mut light, 1, TransportMode::Importance, stats) {
                break;
            }
        }
    }
    let pixels = cam.pixel_count() as u64;
    let pixel = (i + offset) % pixels;
    let raster = Vec2::new(
        (pixel % cam.width as u64) as f32 + rng.next_f32(),
        (pixel / cam.width as u64) as f32 + rng.next_f32(),
    );
    let lens = PathVertex::lens(cam.sample_lens(Vec2::new(rng.next_f32(), rng.next_f32())));
    let mut eye = vec![lens];
    if let Some(v) = trace(scene, accel, &lens, cam.ray_from_lens(lens.p(), raster).dir, stats) {
        eye.push(v);
        while eye.len() < max_vertices {
            if eye.len() >= RR_FROM && rng.next_f64() >= RR_KEEP {
                break;
            }
            if !extend(scene, accel, &mut rng, &mut eye, 1, TransportMode::Radiance, stats) {
                break;
            }
        }
    }
    (light, eye)
}

/// The connected paths of one bootstrap sample with their weights W (see the module doc).
fn candidates(
    scene: &Scene,
    accel: &Accel,
    (light, eye): (&[PathVertex], &[PathVertex]),
    (mlt, max_vertices): (&MltSettings, usize),
    stats: &mut RayStats,
) -> Vec<(usize, usize, f64)> {
    let mut out = Vec::new();
    let pair = WalkPair::new(scene, light, eye);
    let mut ev = path::Evaluation::default();
    for t in 1..=eye.len() {
        for s in 0..=light.len() {
            let k = s + t;
            let specular = |i: usize| if i < s { light[i].is_specular() } else { eye[k - 1 - i].is_specular() };
            if k > max_vertices || !mlt.chains_take(k, specular) {
                continue;
            }
            // The strategy's own C* first: most candidates end there or at their shadow ray,
            // before their other strategies are evaluated.
            let Some((c, _)) = pair.contribution(scene, s, t) else { continue };
            let l = luminance(c.as_vec3());
            if !(l > 0.0 && l.is_finite()) {
                continue;
            }
            if s > 0 && !visible(scene, accel, &light[s - 1], &eye[t - 1], stats) {
                continue;
            }
            pair.evaluate(scene, s, t, &mut ev);
            let inv = ev.inverse_sum(0..=k, |j| reach(j) * reach(k - j));
            let w = 1.0 / inv;
            if w > 0.0 && w.is_finite() {
                out.push((s, t, w));
            }
        }
    }
    out
}

/// The first connected path of the bootstrap samples (seed `seed`, in sample order) for which
/// `wanted` holds, as a state: a start for benchmarks and tests of single mutations.
pub fn find_state(
    scene: &Scene,
    accel: &Accel,
    seed: u64,
    max_vertices: usize,
    wanted: impl Fn(&State) -> bool,
) -> Option<State> {
    let mut st = RayStats::default();
    for i in 0..1_000_000 {
        let (l, e) = bootstrap_walks(scene, accel, seed, i, 0, max_vertices, &mut st);
        let every = MltSettings { direct: 0, ..Default::default() };
        for (s, t, _) in candidates(scene, accel, (&l, &e), (&every, max_vertices), &mut st) {
            let mut p: Vec<PathVertex> = l[..s].to_vec();
            p.extend(e[..t].iter().rev());
            if let Some(state) = State::new(scene, p)
                && wanted(&state)
            {
                return Some(state);
            }
        }
    }
    None
}

/// One chain.
struct Chain {
    rng: Pcg32,
    state: State,
    rover: Rover,
    proposed: u64,
    accepted: u64,
}

/// What a chain adds to the film in a pass.
type Deposits = Vec<(Vec2, Vec3)>;

/// Renders `scene` with path-space MLT; also returns the chains' statistics. Call
/// [`supported`] first.
pub fn render_mlt(
    scene: &Scene,
    accel: &Accel,
    settings: &OfflineSettings,
    mlt: &MltSettings,
    progress: &dyn Progress,
) -> (RenderOutput, MltStats) {
    let start = Instant::now();
    let cam = &scene.camera;
    let mut film = Film::new(cam.width, cam.height, settings.filter, false);
    let mut stats = RayStats::default();
    let seed = settings.seed;
    let max_vertices = settings.max_depth as usize + 2;
    let lengths = (mlt, max_vertices);
    let cx = Context { scene, accel, max_vertices };
    let offset = Pcg32::from_words(&[seed, TAG_OFFSET]).next_u32() as u64;

    // Bootstrap: b and the weights chains start from.
    let n_boot = mlt.bootstrap as u64;
    let boot: Vec<(f64, RayStats)> = (0..n_boot)
        .into_par_iter()
        .map(|i| {
            let mut st = RayStats::default();
            let (l, e) = bootstrap_walks(scene, accel, seed, i, offset, max_vertices, &mut st);
            let total = candidates(scene, accel, (&l, &e), lengths, &mut st).iter().map(|c| c.2).sum();
            st.samples += 1;
            (total, st)
        })
        .collect();
    let mut cdf = Vec::with_capacity(boot.len());
    let mut total = 0.0f64;
    for (w, st) in &boot {
        stats += *st;
        total += w;
        cdf.push(total);
    }
    let mut chain_stats = MltStats {
        b: total / n_boot as f64,
        bootstrap_nonzero: boot.iter().filter(|(w, _)| *w > 0.0).count() as u64,
        ..Default::default()
    };
    drop(boot);
    let b = chain_stats.b;
    if !(b > 0.0) && mlt.direct == 0 {
        // Nothing in the bootstrap reached the camera: a black image.
        settings.budget.start_progress(progress);
        progress.finish();
        film.add_splat_pass();
        let spp = match settings.budget {
            Budget::Samples(n) => n,
            Budget::Time(_) => 1,
        };
        return (RenderOutput { film, stats, spp, elapsed: start.elapsed() }, chain_stats);
    }

    // Chains, each from a connected path chosen ∝ W (none when only the direct part has light).
    let n_chains = if b > 0.0 { mlt.chains as u64 } else { 0 };
    let pixels = cam.pixel_count() as u64;
    let mut chains: Vec<Chain> = (0..n_chains)
        .into_par_iter()
        .map(|c| {
            let mut pick = Pcg32::from_words(&[seed, TAG_START, c]);
            let mut st = RayStats::default();
            let u = pick.next_f64() * total;
            let i = cdf.partition_point(|&x| x <= u).min(cdf.len() - 1);
            let (l, e) = bootstrap_walks(scene, accel, seed, i as u64, offset, max_vertices, &mut st);
            let cands = candidates(scene, accel, (&l, &e), lengths, &mut st);
            let sum: f64 = cands.iter().map(|c| c.2).sum();
            let mut u = pick.next_f64() * sum;
            let &(s, t, _) = cands
                .iter()
                .find(|c| {
                    let hit = u < c.2;
                    u -= c.2;
                    hit
                })
                .or(cands.last())
                .expect("a bootstrap sample chosen ∝ its weight has a candidate");
            let mut p: Vec<PathVertex> = l[..s].to_vec();
            p.extend(e[..t].iter().rev());
            let state = State::new(scene, p).expect("a bootstrap candidate has a contribution");
            let rover = Rover::new(seed, c, pixels);
            Chain { rng: Pcg32::from_words(&[seed, TAG_CHAIN, c]), state, rover, proposed: 0, accepted: 0 }
        })
        .collect();
    drop(cdf);

    let per_chain = |c: usize, n: u64| -> u64 {
        let k = mlt.chains as u64;
        n / k + u64::from((c as u64) < n % k)
    };
    // The direct part: path-traced samples restricted to it, `mlt.direct` a pixel each pass,
    // averaged as pixel samples under the splats.
    let direct_settings = OfflineSettings { aovs: false, ..settings.clone() };
    let tiles = film.tiles(super::TILE);
    let only_direct = super::pt::PathFilter { mlt_direct_part: true, ..Default::default() };
    let direct_fn = |raster: Vec2, sampler: &mut PixelSampler, _: &mut FilmTile, st: &mut RayStats| {
        let ray = cam.generate_ray(raster, sampler.next_2d());
        super::pt::radiance_of_length(scene, accel, ray, sampler, settings.max_depth, &only_direct, st)
    };
    let spp = settings.budget.drive(start, progress, |pass| {
        if mlt.direct > 0 {
            let first = pass * mlt.direct;
            stats +=
                super::pixel_pass(scene, &direct_settings, &mut film, &tiles, first..first + mlt.direct, &direct_fn);
        }
        let results: Vec<(Deposits, RayStats, [MutationCounts; MutationKind::ALL.len()], u64, u64)> = chains
            .par_iter_mut()
            .enumerate()
            .map(|(c, ch)| {
                let n = per_chain(c, pixels);
                let mut deposits = Vec::with_capacity(2 * n as usize);
                let mut st = RayStats::default();
                let mut counts = [MutationCounts::default(); MutationKind::ALL.len()];
                let mut vertex_steps = 0u64;
                let mut idle = 0u64;
                for _ in 0..n {
                    st.samples += 1;
                    vertex_steps += ch.state.path.len() as u64;
                    let Some(kind) = mlt.choose(&ch.state, ch.rng.next_f64()) else {
                        idle += 1;
                        deposits.push((ch.state.raster(), ch.state.eval.colour() * b as f32));
                        continue;
                    };
                    let slot = MutationKind::ALL.iter().position(|&k| k == kind).expect("a known kind");
                    counts[slot].proposed += 1;
                    ch.proposed += 1;
                    let proposal = if kind == MutationKind::Subpath {
                        let raster = ch.rover.next_raster(cam.width, &mut ch.rng);
                        LensSubpath.propose_at(&cx, &ch.state, raster, &mut ch.rng, &mut st)
                    } else {
                        kind.mutation().propose(&cx, &ch.state, &mut ch.rng, &mut st)
                    };
                    let Some(p) = proposal else {
                        deposits.push((ch.state.raster(), ch.state.eval.colour() * b as f32));
                        continue;
                    };
                    counts[slot].made += 1;
                    // Paths of the direct part are not the chains' (target 0 there).
                    let y = &p.state.path;
                    let a = if mlt.chains_take(y.len(), |i| y[i].is_specular()) { p.accept } else { 0.0 };
                    if a > 0.0 {
                        deposits.push((p.state.raster(), p.state.eval.colour() * (a * b) as f32));
                    }
                    if a < 1.0 {
                        deposits.push((ch.state.raster(), ch.state.eval.colour() * ((1.0 - a) * b) as f32));
                    }
                    if ch.rng.next_f64() < a {
                        counts[slot].accepted += 1;
                        ch.accepted += 1;
                        ch.state = p.state;
                    }
                }
                (deposits, st, counts, vertex_steps, idle)
            })
            .collect();
        let mut tile = FilmTile::new(0, 0, 0, 0, false);
        for (deposits, st, counts, vs, idle) in results {
            tile.splats.extend(deposits);
            chain_stats.vertex_steps += vs;
            chain_stats.idle_steps += idle;
            stats += st;
            for (a, c) in chain_stats.counts.iter_mut().zip(counts) {
                a.proposed += c.proposed;
                a.made += c.made;
                a.accepted += c.accepted;
            }
        }
        film.merge_tile(&tile);
        film.add_splat_pass();
        1
    });
    chain_stats.stuck_chains = chains.iter().filter(|c| c.proposed >= 32 && c.accepted == 0).count() as u64;
    (RenderOutput { film, stats, spp, elapsed: start.elapsed() }, chain_stats)
}
