//! The one interface every stochastic stage draws its random numbers through.

use std::sync::LazyLock;

use glam::{Vec2, vec2};
use sobol_burley::parts::{hash, owen_scramble_rev, sobol_rev, u32_to_f32_norm};

use super::rng::Pcg32;

/// A source of uniform samples in [0, 1).
///
/// Estimators take `&mut impl Sampler` and never own their randomness, so the same estimator can
/// be driven by independent streams (path tracing, VPL sampling) or by a primary-sample-space
/// Markov chain that replays and perturbs the numbers (Kelemen et al. 2002).
pub trait Sampler {
    /// The next uniform number in [0, 1).
    fn next_1d(&mut self) -> f32;

    /// The next two uniform numbers in [0, 1)².
    #[inline]
    fn next_2d(&mut self) -> Vec2 {
        let x = self.next_1d();
        let y = self.next_1d();
        vec2(x, y)
    }
}

/// Independent uniform samples from a hash-seeded PCG32 stream.
#[derive(Clone, Debug)]
pub struct IndependentSampler {
    rng: Pcg32,
}

impl IndependentSampler {
    /// A stream fully determined by `seed`.
    pub fn new(seed: u64) -> Self {
        IndependentSampler { rng: Pcg32::new(seed) }
    }

    /// The stream of one pixel sample: a hash of (seed, pixel index, sample index), so images do
    /// not depend on the order in which threads visit pixels.
    pub fn for_pixel_sample(seed: u64, pixel: u64, sample: u64) -> Self {
        IndependentSampler { rng: Pcg32::from_words(&[seed, 0x0050_4958_454c, pixel, sample]) }
    }

    /// A stream for any other purpose, keyed by a tag and indices (chain, step, light path...).
    pub fn for_stream(seed: u64, tag: u64, index: u64) -> Self {
        IndependentSampler { rng: Pcg32::from_words(&[seed, tag, index]) }
    }

    /// The underlying generator, for integer draws.
    pub fn rng(&mut self) -> &mut Pcg32 {
        &mut self.rng
    }
}

impl Sampler for IndependentSampler {
    #[inline]
    fn next_1d(&mut self) -> f32 {
        self.rng.next_f32()
    }
}

/// Owen-scrambled Sobol samples for one pixel sample (Burley 2020, "Practical Hash-based Owen
/// Scrambling", with the hash and scramble of the `sobol_burley` crate), padded: each of the
/// first [`SOBOL_SLOTS`] two-dimensional draws takes a fresh slot whose numbers are Sobol
/// dimensions 0 and 1 under the slot's own index shuffle and Owen scramble; one-dimensional
/// draws and later draws are independent. Within a pixel the samples of one slot form a
/// (0, 2)-sequence (the pixel position, a light point, a BSDF direction of one bounce); across
/// slots and pixels they are independent. Every number is uniform in [0, 1), so an estimator's
/// expectation does not change; its variance falls where the integrand is smooth in those
/// slots (anti-aliasing, soft shadows, the first bounces' directions).
#[derive(Clone, Debug)]
pub struct SobolSampler {
    /// The pixel's seed, hashed from (render seed, pixel, sample index / 2¹⁶).
    seed: u64,
    /// The sample's index in the pixel's sequence (below 2¹⁶), bits reversed.
    index_rev: u32,
    /// The next slot.
    slot: u32,
    /// The one-dimensional draws and those after the first [`SOBOL_SLOTS`] slots.
    tail: Pcg32,
}

/// Two-dimensional draws per pixel sample that take Sobol numbers. The variance reduction fades
/// with the dimension; 6 slots cover the pixel position, the lens and the light point and
/// direction of two bounces of `pt`.
pub const SOBOL_SLOTS: u32 = 6;

/// Samples per pixel in one scrambled Sobol sequence; later samples start a new, independently
/// scrambled one.
const SOBOL_SEQUENCE: u64 = 1 << 16;

/// Sobol dimensions 0 and 1 of a bit-reversed 16-bit index (its top 16 bits), tabulated by byte:
/// the sequence is linear over GF(2) in the index bits, so two lookups replace the crate's loop
/// over up to 16 bits (24 → ~5 ns a draw).
static SOBOL_BYTES: LazyLock<[[[u32; 256]; 2]; 2]> = LazyLock::new(|| {
    let mut t = [[[0; 256]; 2]; 2];
    for (dim, tables) in t.iter_mut().enumerate() {
        for b in 0..256u32 {
            tables[0][b as usize] = sobol_rev(b << 24, dim as u32);
            tables[1][b as usize] = sobol_rev(b << 16, dim as u32);
        }
    }
    t
});

impl SobolSampler {
    /// The samples of sample `sample` of pixel `pixel`, under render seed `seed`.
    pub fn for_pixel_sample(seed: u64, pixel: u64, sample: u64) -> Self {
        let block = sample / SOBOL_SEQUENCE;
        let pixel_seed = super::rng::hash_words(&[seed, 0x0053_4f42_4f4c, pixel, block]);
        SobolSampler {
            seed: pixel_seed,
            index_rev: ((sample % SOBOL_SEQUENCE) as u32).reverse_bits(),
            slot: 0,
            tail: Pcg32::new(pixel_seed ^ sample.wrapping_mul(0xd1b5_4a32_d192_ed03)),
        }
    }

    /// Point `index` (below 2¹⁶) of slot `slot_seed`'s scrambled two-dimensional sequence.
    #[inline]
    pub fn point(index: u32, slot_seed: u32) -> Vec2 {
        Self::point_rev(index.reverse_bits(), slot_seed)
    }

    /// [`SobolSampler::point`] of the bit-reversed index.
    #[inline]
    fn point_rev(index_rev: u32, slot_seed: u32) -> Vec2 {
        let tables = &*SOBOL_BYTES;
        // Shuffle the index (an Owen scramble of its reversed bits keeps every power-of-two
        // prefix of the sequence a net), then scramble each dimension on its own.
        let i = owen_scramble_rev(index_rev, hash(slot_seed ^ 0x5f3a_9c1d)) & 0xffff_0000;
        let dim = |d: usize, salt: u32| {
            let sobol = tables[d][0][(i >> 24) as usize] ^ tables[d][1][(i >> 16 & 0xff) as usize];
            u32_to_f32_norm(owen_scramble_rev(sobol, hash(slot_seed.wrapping_mul(0x2c1b_3c6d) ^ salt)).reverse_bits())
        };
        vec2(dim(0, 0x68e3_1da4), dim(1, 0xb5ad_4ece))
    }
}

impl Sampler for SobolSampler {
    #[inline]
    fn next_1d(&mut self) -> f32 {
        self.tail.next_f32()
    }

    #[inline]
    fn next_2d(&mut self) -> Vec2 {
        if self.slot >= SOBOL_SLOTS {
            let x = self.tail.next_f32();
            return vec2(x, self.tail.next_f32());
        }
        let slot_seed = super::rng::mix64(self.seed ^ u64::from(self.slot).wrapping_mul(0x9e37_79b9_7f4a_7c15)) as u32;
        self.slot += 1;
        Self::point_rev(self.index_rev, slot_seed)
    }
}

/// The sampler of one pixel sample in the offline modes, as `--sampler` chose it.
#[derive(Clone, Debug)]
pub enum PixelSampler {
    /// Independent uniform numbers.
    Independent(IndependentSampler),
    /// Scrambled Sobol numbers, stratified per pixel.
    Sobol(SobolSampler),
}

/// Which [`PixelSampler`] the offline modes draw through.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PixelSamplerKind {
    /// Independent uniform numbers: every pixel sample its own hashed PCG32 stream.
    Independent,
    /// Padded Owen-scrambled Sobol: the default (lower variance at the same expectation).
    #[default]
    Sobol,
}

impl PixelSampler {
    /// The sampler of sample `sample` of pixel `pixel`.
    pub fn for_pixel_sample(kind: PixelSamplerKind, seed: u64, pixel: u64, sample: u64) -> Self {
        match kind {
            PixelSamplerKind::Independent => {
                PixelSampler::Independent(IndependentSampler::for_pixel_sample(seed, pixel, sample))
            }
            PixelSamplerKind::Sobol => PixelSampler::Sobol(SobolSampler::for_pixel_sample(seed, pixel, sample)),
        }
    }
}

impl Sampler for PixelSampler {
    #[inline]
    fn next_1d(&mut self) -> f32 {
        match self {
            PixelSampler::Independent(s) => s.next_1d(),
            PixelSampler::Sobol(s) => s.next_1d(),
        }
    }

    #[inline]
    fn next_2d(&mut self) -> Vec2 {
        match self {
            PixelSampler::Independent(s) => s.next_2d(),
            PixelSampler::Sobol(s) => s.next_2d(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The first 2^k points of a slot form a (0, k, 2)-net: every elementary box of area 2^-k
    /// (2^a × 2^(k−a) cells) holds exactly one point. Independent or badly scrambled numbers
    /// fail this at once (~37 % of the cells of a random set are empty).
    #[test]
    fn each_slot_is_a_0_2_net_at_every_power_of_two() {
        for slot_seed in [0u32, 1, 0xdead_beef, 12345] {
            for k in [4u32, 8, 10] {
                let n = 1u32 << k;
                let pts: Vec<Vec2> = (0..n).map(|i| SobolSampler::point(i, slot_seed)).collect();
                for a in 0..=k {
                    let (cx, cy) = (1u32 << a, 1u32 << (k - a));
                    let mut cells = vec![0u32; n as usize];
                    for p in &pts {
                        assert!((0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y));
                        let (x, y) = ((p.x * cx as f32) as u32, (p.y * cy as f32) as u32);
                        cells[(y * cx + x) as usize] += 1;
                    }
                    assert!(cells.iter().all(|&c| c == 1), "seed {slot_seed} k {k} a {a}: {cells:?}");
                }
            }
        }
    }

    /// A pixel's slots are independent of each other and of other pixels: the correlation of the
    /// x of slot 0 with slot 1 (same sample) and with slot 0 of the next pixel vanishes, within
    /// 4 standard errors (1/√N) over N = 16384 samples.
    #[test]
    fn slots_and_pixels_are_uncorrelated() {
        let n = 16384u64;
        let corr = |a: &[f32], b: &[f32]| {
            let m = |v: &[f32]| v.iter().map(|&x| x as f64).sum::<f64>() / v.len() as f64;
            let (ma, mb) = (m(a), m(b));
            let cov: f64 = a.iter().zip(b).map(|(&x, &y)| (x as f64 - ma) * (y as f64 - mb)).sum();
            let va: f64 = a.iter().map(|&x| (x as f64 - ma).powi(2)).sum();
            let vb: f64 = b.iter().map(|&y| (y as f64 - mb).powi(2)).sum();
            cov / (va * vb).sqrt()
        };
        let (mut s0, mut s1, mut other) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..n {
            let mut s = SobolSampler::for_pixel_sample(7, 3, i);
            s0.push(s.next_2d().x);
            s1.push(s.next_2d().x);
            other.push(SobolSampler::for_pixel_sample(7, 4, i).next_2d().x);
        }
        let bound = 4.0 / (n as f64).sqrt();
        assert!(corr(&s0, &s1).abs() < bound, "slot 0 vs 1: {}", corr(&s0, &s1));
        assert!(corr(&s0, &other).abs() < bound, "pixel 3 vs 4: {}", corr(&s0, &other));
    }

    /// Every number is uniform in [0, 1), also past the Sobol slots, for one-dimensional draws
    /// and past a sequence's 2^16 samples: the mean of x and of x² over many pixels match ½ and
    /// ⅓ within 4 standard errors.
    #[test]
    fn every_draw_is_uniform() {
        let pixels = 4096u64;
        for sample in [0u64, 5, (1 << 16) + 3] {
            for draw in 0..10 {
                let (mut m1, mut m2) = (0.0f64, 0.0f64);
                for p in 0..pixels {
                    let mut s = SobolSampler::for_pixel_sample(11, p, sample);
                    for _ in 0..draw {
                        s.next_2d();
                    }
                    let x = if draw % 3 == 2 { s.next_1d() } else { s.next_2d().y } as f64;
                    assert!((0.0..1.0).contains(&x));
                    m1 += x;
                    m2 += x * x;
                }
                let (m1, m2) = (m1 / pixels as f64, m2 / pixels as f64);
                let se1 = (1.0f64 / 12.0 / pixels as f64).sqrt();
                let se2 = (4.0f64 / 45.0 / pixels as f64).sqrt();
                assert!((m1 - 0.5).abs() < 4.0 * se1, "sample {sample} draw {draw}: mean {m1}");
                assert!((m2 - 1.0 / 3.0).abs() < 4.0 * se2, "sample {sample} draw {draw}: mean² {m2}");
            }
        }
    }
}
