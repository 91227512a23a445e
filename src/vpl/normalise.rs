//! MIR's normalisation (papers/002 §5.4–5.5): each VPL location's camera response P′,
//! estimated from batches of camera probes ([`ProbeDensity`]) with shadow rays placed ∝ the
//! unshadowed response ([`visibility_samples`]), and the VPL's radiance scaled by P_i / P̂′_i
//! ([`ProbeSums::scaled`]). The chains that produce the locations are in [`super::metropolis`].

use std::sync::OnceLock;

use rayon::prelude::*;

use super::kernel::{Prepared, VplLanes};
use super::mutation::{Context, PathState};
use super::screen::ProbeDensity;
use super::set::{Vpl, VplSet};
use super::transfer::Receiver;
use crate::accel::batch::ShadowBatch;
use crate::color::luminance;
use crate::sampling::{IndependentSampler, Pcg32, Sampler};
use crate::stats::RayStats;

const TAG_PROBE: u64 = 0x0050_524f_4245;
const TAG_VISIBILITY: u64 = 0x0056_4953_4942;

/// How the locations of a run are measured.
pub(super) struct Measure {
    /// Probe batches available; a location seen by fewer than `min_hits` probes of the first
    /// batches is measured with the next batch, up to this many.
    pub batches: usize,
    /// Probe hits a location's response estimate should rest on.
    pub min_hits: usize,
    /// Shadow rays a location's response takes from one batch (see [`visibility_samples`]).
    pub visibility_samples: usize,
    /// The bound on G of the chains' target, which P′ shares (see `mirpath::TARGET_CLAMP`).
    pub g_target: f32,
}

impl Measure {
    /// Each location's probe sums (in the order of `locations`) and the rays traced. Each
    /// batch has its own seed, so the result does not depend on which thread traces it. The
    /// first batch is traced in parallel up front; most VPLs are seen by enough of its probes.
    /// Later batches are traced when a VPL first needs them, serially inside the parallel loop
    /// (a parallel initialiser could steal a task that asks for the same batch and re-enter
    /// its own initialisation).
    pub fn locations(
        &self,
        ctx: &Context,
        locations: &[(PathState, u64)],
        density: &ProbeDensity,
        seed: u64,
    ) -> (Vec<ProbeSums>, RayStats) {
        let batch_seed = |b: usize| seed ^ (b as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        let probe_sets: Vec<OnceLock<ProbeBatch>> = (0..self.batches).map(|_| OnceLock::new()).collect();
        let _ = probe_sets[0].set(probes(ctx, density, batch_seed(0), true));
        let batch = |b: usize| probe_sets[b].get_or_init(|| probes(ctx, density, batch_seed(b), false));
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
                for b in 0..self.batches {
                    if active == 0 {
                        break;
                    }
                    let ProbeBatch { receivers, pixels, weights, cell, rays: count, .. } = batch(b);
                    lit.iter_mut().for_each(Vec::clear);
                    for (i, (r, pt)) in receivers.iter().enumerate() {
                        lanes.each_unshadowed(&set, pt, r, active, self.g_target, |j, c| {
                            let y = luminance(c) * weights[i];
                            if y > 0.0 {
                                lit[j].push((i as u32, y));
                            }
                        });
                    }
                    let mut add = |_, v: VisibilitySample| {
                        let i = v.probe as usize;
                        sums[v.lane as usize].add(v, pixels[i], weights[i], *cell)
                    };
                    for j in (0..chunk.len()).filter(|j| active >> j & 1 != 0) {
                        let xi = Pcg32::from_words(&[seed, TAG_VISIBILITY, (8 * c + j) as u64, b as u64]).next_f64();
                        let target = set.position[j];
                        visibility_samples(&lit[j], self.visibility_samples, xi, |i, sample| {
                            let pt = &receivers[i as usize].1;
                            let sample = VisibilitySample { lane: j as u32, ..sample };
                            rays.push(
                                pt.origin_towards(target),
                                target,
                                j as u32,
                                sample,
                                ctx.accel,
                                &mut hints,
                                &mut st,
                                &mut add,
                            );
                        });
                    }
                    rays.trace(ctx.accel, &mut hints, &mut st, &mut add);
                    let measuring = active;
                    for (j, p) in sums.iter_mut().enumerate().filter(|(j, _)| measuring >> j & 1 != 0) {
                        p.rays_used += count;
                        if p.hits >= self.min_hits as f64 {
                            active &= !(1 << j);
                        }
                    }
                }
                (sums, st)
            })
            .collect();
        let mut rays = RayStats::default();
        let mut all = Vec::with_capacity(locations.len());
        for (sums, st) in measured {
            rays += st;
            all.extend(sums);
        }
        for b in probe_sets.iter().filter_map(OnceLock::get) {
            rays += b.stats;
        }
        (all, rays)
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
/// it visible (widened by half a uniform probe cell each side; `[u32::MAX, u32::MAX, 0, 0]` while
/// none did).
#[derive(Clone, Copy, Debug)]
pub(super) struct ProbeSums {
    sum: f64,
    sum2: f64,
    rays_used: usize,
    hits: f64,
    area: f64,
    /// The screen rectangle where probes saw the location (see above).
    pub rect: [u32; 4],
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
    /// The estimated share of the image's pixels that see the location.
    pub fn footprint(&self) -> f32 {
        (self.area / self.rays_used.max(1) as f64) as f32
    }

    /// Adds an unblocked visibility sample; its probe lies at `pixel` with balance weight
    /// `weight`, in probe cells of `cell` pixels.
    fn add(&mut self, v: VisibilitySample, pixel: [u32; 2], weight: f32, cell: [u32; 2]) {
        self.sum += v.sum;
        self.sum2 += v.sum2;
        self.hits += v.hits;
        self.area += v.hits * weight as f64;
        // Half a cell each side: the footprint reaches past its outermost probes by less than
        // the spacing of the uniform probes (and the guided ones are denser where it lies).
        let (hx, hy) = (cell[0].div_ceil(2), cell[1].div_ceil(2));
        let r = &mut self.rect;
        r[0] = r[0].min(pixel[0].saturating_sub(hx));
        r[1] = r[1].min(pixel[1].saturating_sub(hy));
        r[2] = r[2].max(pixel[0] + hx);
        r[3] = r[3].max(pixel[1] + hy);
    }

    /// The VPL `vpl` (location `group`, `k` chain states, power `p_i`) with its radiance scaled
    /// by P_i / P'_i (module doc); None when no probe saw it or P_i is not finite.
    pub fn scaled(&self, vpl: Vpl, group: u32, k: u64, p_i: f64, npix: f64) -> Option<Vpl> {
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
