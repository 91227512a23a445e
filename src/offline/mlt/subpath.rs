//! The lens sub-path mutation and its rover (Veach 1997 §11.4.2; Fischer §3.5.3,
//! docs/bibliography.md).
//!
//! The mutation replaces the lens sub-path of a path … x_{a−1} | x_a S* E — the lens, the
//! specular vertices it sees through, and the first non-specular vertex x_a — by a new one
//! made as a camera walk makes it: a lens point, a ray through a new raster position, the same
//! number of specular bounces with their events sampled by the BSDFs, and a non-specular vertex
//! joined to x_{a−1} with a shadow ray (or, when a = 0, a light reached at the end of the
//! chain). The new sub-path does not depend on the old one beyond its length, so
//! `T(ȳ|x̄) = p_E(y_a … y_{k−1})`, the camera sub-path's density, and with
//! `f / p_E = p_L(x_0 … x_{a−1}) · C*_a` (the kept light vertices are the same on both sides):
//! `a(ȳ|x̄) = min(1, lum C*_a(ȳ) / lum C*_a(x̄))`, evaluated as the path's own strategies are.
//! A walk that hits a non-specular vertex early or a specular one last proposes nothing (the
//! state stays); that probability is part of the same density on both sides.
//!
//! **Rover**: the raster positions of the chains' lens sub-path mutations are stratified over
//! the pixels across the chains (Fischer's rover; in Veach's set this mutation is the one that
//! spreads the samples evenly over the image): chain c's n-th lens sub-path proposal lands in pixel
//! `(o_n + c·g) mod P` (P pixels, g coprime to P near P/φ so that the chains spread over the
//! image, o_n uniform and independent for each n) at a uniform position inside it. So the n-th
//! proposals of all the chains fall in distinct pixels spread evenly over the image, while each
//! chain on its own sees independent uniform positions, the density its acceptance assumes. (A
//! deterministic sweep within one chain would not do: proposing alternately from two pixels of
//! weight 2 and 1, an independence chain spends ¼ of its time on the second, not ⅓.)

use glam::Vec2;

use super::mutation::{Context, Mutation, Proposal, State, first_diffuse_from_lens, joins};
use super::path::{PathVertex, extend, trace, uniform_raster};
use crate::bsdf::TransportMode;
use crate::sampling::Pcg32;
use crate::stats::RayStats;

/// The lens sub-path mutation.
pub struct LensSubpath;

impl LensSubpath {
    /// Proposes from `x` with the new camera ray through `raster` (uniform over the image: the
    /// rover's, or [`uniform_raster`]).
    pub fn propose_at(
        &self,
        cx: &Context,
        x: &State,
        raster: Vec2,
        rng: &mut Pcg32,
        stats: &mut RayStats,
    ) -> Option<Proposal> {
        let (scene, accel) = (cx.scene, cx.accel);
        let cam = &scene.camera;
        let xp = &x.path;
        let k = xp.len();
        if !self.applies(x) {
            return None;
        }
        // a: the first non-specular vertex seen from the lens; the light side keeps 0 … a − 1.
        let a = first_diffuse_from_lens(xp);
        let t = k - a;
        let lens = PathVertex::lens(cam.sample_lens(Vec2::new(rng.next_f32(), rng.next_f32())));
        let mut eye = vec![lens];
        eye.push(trace(scene, accel, &lens, cam.ray_from_lens(lens.p(), raster).dir, stats)?);
        while eye.len() < t {
            if !eye[eye.len() - 1].is_specular() {
                return None;
            }
            if !extend(scene, accel, rng, &mut eye, 1, TransportMode::Radiance, stats) {
                return None;
            }
        }
        if eye[t - 1].is_specular() {
            return None;
        }
        let mut path: Vec<PathVertex> = xp[..a].to_vec();
        path.extend(eye.iter().rev());
        // When a = 0 (S* E from a light) the chain must end on an emitting surface.
        if !joins(cx, &path, a, stats) {
            return None;
        }
        let state = State::new(scene, path)?;
        let (new_l, old_l) = (state.eval.lum(a), x.eval.lum(a));
        Some(Proposal::with_ratio(state, new_l, old_l))
    }
}

impl Mutation for LensSubpath {
    fn name(&self) -> &'static str {
        "subpath"
    }

    /// Paths … (L|D) | D S* E, and L S* E.
    fn applies(&self, x: &State) -> bool {
        let a = first_diffuse_from_lens(&x.path);
        !(x.path[a].is_specular() || (a >= 1 && x.path[a - 1].is_specular()))
    }

    /// With a uniform raster position (the chains use the rover's: [`Rover`]).
    fn propose(&self, cx: &Context, x: &State, rng: &mut Pcg32, stats: &mut RayStats) -> Option<Proposal> {
        let raster = uniform_raster(cx.scene, rng);
        self.propose_at(cx, x, raster, rng, stats)
    }
}

/// One chain's rover (see the module doc).
#[derive(Clone, Debug)]
pub struct Rover {
    /// The render's seed (the offsets' stream).
    seed: u64,
    /// This chain's index c, and its proposals so far n.
    chain: u64,
    next: u64,
    /// Pixels P and the multiplier g.
    pixels: u64,
    step: u64,
}

/// The offsets' stream tag.
const TAG_ROVER: u64 = 0x4d4c_5452_4f56;

impl Rover {
    /// Chain `chain`'s rover over an image of `pixels` pixels for the render's `seed`.
    pub fn new(seed: u64, chain: u64, pixels: u64) -> Rover {
        let pixels = pixels.max(1);
        Rover { seed, chain, next: 0, pixels, step: coprime_step(pixels) }
    }

    /// The pixel index of this chain's next proposal.
    pub fn next_pixel(&mut self) -> u64 {
        let p = self.pixels;
        let o = Pcg32::from_words(&[self.seed, TAG_ROVER, self.next]).next_below(p.min(u32::MAX as u64) as u32) as u64;
        self.next += 1;
        // c mod P, g and o are below P ≤ 2^32 for any image a camera accepts: the sum fits.
        ((self.chain % p) * self.step % p + o) % p
    }

    /// The next raster position: a uniform point in the next pixel of an image `width` wide.
    pub fn next_raster(&mut self, width: u32, rng: &mut Pcg32) -> Vec2 {
        let p = self.next_pixel();
        let w = width.max(1) as u64;
        Vec2::new((p % w) as f32 + rng.next_f32(), (p / w) as f32 + rng.next_f32())
    }
}

/// The integer nearest P/φ (φ the golden ratio) that is coprime to `p`: a step that visits every
/// residue, consecutive multiples far apart.
fn coprime_step(p: u64) -> u64 {
    if p <= 2 {
        return 1;
    }
    let start = ((p as f64) / 1.618_033_988_749_895).round() as u64;
    (0..p).flat_map(|d| [start + d, start.wrapping_sub(d)]).find(|&g| g > 0 && g < p && gcd(g, p) == 1).unwrap_or(1)
}

fn gcd(mut a: u64, mut b: u64) -> u64 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The n-th proposals of up to P chains fall in distinct pixels, and one chain's pixels
    /// over many proposals cover the image evenly (each pixel within 5 standard deviations of
    /// its expected count).
    #[test]
    fn the_rover_stratifies_across_chains_and_is_uniform_along_one() {
        for (pixels, chains) in [(1u64, 1u64), (12, 5), (768, 768), (49_152, 1000), (97, 3)] {
            let mut rovers: Vec<Rover> = (0..chains).map(|c| Rover::new(7, c, pixels)).collect();
            for round in 0..4 {
                let mut seen = vec![false; pixels as usize];
                for r in &mut rovers {
                    let p = r.next_pixel() as usize;
                    assert!(!seen[p], "{pixels} pixels, {chains} chains, round {round}: pixel {p} twice");
                    seen[p] = true;
                }
            }
        }
        let (pixels, n) = (64u64, 64_000u64);
        let mut r = Rover::new(3, 5, pixels);
        let mut counts = vec![0u64; pixels as usize];
        for _ in 0..n {
            counts[r.next_pixel() as usize] += 1;
        }
        let (e, sd) = ((n / pixels) as f64, ((n / pixels) as f64).sqrt());
        assert!(counts.iter().all(|&c| (c as f64 - e).abs() < 5.0 * sd), "{counts:?}");
    }
}
