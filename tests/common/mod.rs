//! Shared helpers of the statistical image tests.
//!
//! An [`Estimate`] is the mean of K independent renders (batches) with the per-pixel variance of
//! that mean estimated from the spread of the batches. Two estimates of the same image agree
//! when, over blocks of pixels, the squared differences are explained by their variances:
//! `mean_b (A_b − B_b)² / (σ²_A,b + σ²_B,b)` stays near 1 ([`agreement`]). The bound used in the
//! tests is derived from the distribution of that statistic, not tuned to pass.
#![allow(dead_code, clippy::needless_range_loop)]

use std::path::PathBuf;

use glam::Vec3;
use mirage::film::Image;
use mirage::output;

/// Mean of K batches and the variance of that mean per pixel; the batches are kept so that
/// block sums can get their own variance (pixels of VPL images are correlated).
pub struct Estimate {
    pub mean: Image,
    pub var_of_mean: Vec<Vec3>,
    pub batches: usize,
    pub images: Vec<Image>,
}

impl Estimate {
    /// Combines batch images (all the same size).
    pub fn from_batches(batches: &[Image]) -> Estimate {
        let k = batches.len();
        assert!(k >= 2);
        let (w, h) = (batches[0].width, batches[0].height);
        let n = batches[0].data.len();
        let mut mean = Image::new(w, h);
        let mut var = vec![Vec3::ZERO; n];
        for i in 0..n {
            let m = batches.iter().map(|b| b.data[i]).sum::<Vec3>() / k as f32;
            let v = batches.iter().map(|b| (b.data[i] - m) * (b.data[i] - m)).sum::<Vec3>() / (k - 1) as f32;
            mean.data[i] = m;
            var[i] = v / k as f32;
        }
        Estimate { mean, var_of_mean: var, batches: k, images: batches.to_vec() }
    }

    /// Mean and variance of the mean of the whole-image sum.
    fn whole(e: &Estimate) -> (Vec3, Vec3) {
        let sums: Vec<Vec3> = e.images.iter().map(|img| img.data.iter().copied().sum::<Vec3>()).collect();
        let k = sums.len() as f32;
        let mean = sums.iter().copied().sum::<Vec3>() / k;
        let var = sums.iter().map(|s| (*s - mean) * (*s - mean)).sum::<Vec3>() / (k - 1.0) / k;
        (mean, var)
    }

    /// Per-batch sums over a block of pixels (one value per batch and channel).
    fn block_sums(&self, bx: u32, by: u32, block: u32) -> Vec<Vec3> {
        self.images
            .iter()
            .map(|img| {
                let mut s = Vec3::ZERO;
                for y in by * block..(by + 1) * block {
                    for x in bx * block..(bx + 1) * block {
                        s += img.get(x, y);
                    }
                }
                s
            })
            .collect()
    }
}

/// Student's t density with ν degrees of freedom (unnormalised).
fn t_density(t: f64, nu: f64) -> f64 {
    (1.0 + t * t / nu).powf(-(nu + 1.0) / 2.0)
}

/// Two-sided tail probability P(|T| > t) for Student's t with ν degrees of freedom, by
/// numerical integration of the density (Simpson's rule on a substituted variable).
pub fn t_two_sided_tail(t: f64, nu: f64) -> f64 {
    // Integrate over u in (0, 1] with t' = tan(u·π/2) to cover [0, ∞).
    let integral = |lo: f64, hi: f64| {
        let n = 4000;
        let h = (hi - lo) / n as f64;
        let f = |u: f64| {
            let x = (u * std::f64::consts::FRAC_PI_2).tan();
            let dx = std::f64::consts::FRAC_PI_2 / (u * std::f64::consts::FRAC_PI_2).cos().powi(2);
            if dx.is_finite() { t_density(x, nu) * dx } else { 0.0 }
        };
        let mut s = f(lo) + f(hi - 1e-12);
        for i in 1..n {
            s += f(lo + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
        }
        s * h / 3.0
    };
    let ut = t.atan() / std::f64::consts::FRAC_PI_2;
    let total = integral(0.0, 1.0);
    let tail = integral(ut, 1.0);
    (tail / total).clamp(0.0, 1.0)
}

/// Result of the correlation-robust comparison.
#[derive(Debug)]
pub struct BlockTest {
    /// Largest |t| over blocks and channels.
    pub max_t: f64,
    /// Where it occurred (block x, block y, channel).
    pub at: (u32, u32, usize),
    /// Critical value: P(|T_ν| > critical) = α / terms (Bonferroni), α = 1e-3.
    pub critical: f64,
    /// Number of (block, channel) terms.
    pub terms: usize,
    /// Degrees of freedom ν.
    pub dof: f64,
}

/// Compares two estimates block by block with Welch t statistics whose variances come from
/// the per-batch block sums, and a Bonferroni bound on the largest |t|. Valid whatever the
/// correlation between pixels and between blocks (VPL images share their VPLs everywhere), at
/// the price of less power than [`agreement`], which assumes independent pixels (pt, bdpt).
pub fn block_test(a: &Estimate, b: &Estimate, block: u32) -> BlockTest {
    let (w, h) = (a.mean.width, a.mean.height);
    let stats = |e: &Estimate, bx: u32, by: u32| {
        let sums = e.block_sums(bx, by, block);
        let k = sums.len() as f32;
        let mean = sums.iter().copied().sum::<Vec3>() / k;
        let var = sums.iter().map(|s| (*s - mean) * (*s - mean)).sum::<Vec3>() / (k - 1.0) / k;
        (mean, var)
    };
    let mut max_t = 0.0f64;
    let mut at = (0, 0, 0);
    let mut terms = 0;
    for by in 0..h / block {
        for bx in 0..w / block {
            let (ma, va) = stats(a, bx, by);
            let (mb, vb) = stats(b, bx, by);
            for c in 0..3 {
                let v = (va[c] + vb[c]) as f64;
                let d = (ma[c] - mb[c]) as f64;
                if v <= 1e-20 {
                    assert!(
                        d.abs() <= 1e-4 * (ma[c].abs() + mb[c].abs()) as f64 + 1e-9,
                        "noiseless block differs: {d}"
                    );
                    continue;
                }
                terms += 1;
                let t = d.abs() / v.sqrt();
                if t > max_t {
                    max_t = t;
                    at = (bx, by, c);
                }
            }
        }
    }
    // The whole image as one more term: a global bias shows up here with the most power.
    let (wa, wb) = (Estimate::whole(a), Estimate::whole(b));
    for c in 0..3 {
        let v = (wa.1[c] + wb.1[c]) as f64;
        if v > 1e-20 {
            terms += 1;
            let t = ((wa.0[c] - wb.0[c]) as f64).abs() / v.sqrt();
            if t > max_t {
                max_t = t;
                at = (u32::MAX, u32::MAX, c);
            }
        }
    }
    let dof = (a.batches.min(b.batches) - 1) as f64;
    let target = 1e-3 / terms.max(1) as f64;
    // Bisection for the critical value.
    let (mut lo, mut hi) = (0.0f64, 200.0f64);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if t_two_sided_tail(mid, dof) > target { lo = mid } else { hi = mid }
    }
    BlockTest { max_t, at, critical: hi, terms, dof }
}

/// Asserts the correlation-robust block test, dumping both images on failure.
pub fn assert_agree_blocks(name: &str, a: &Estimate, b: &Estimate, block: u32) {
    let r = block_test(a, b, block);
    let ma = a.mean.mean_luminance();
    let mb = b.mean.mean_luminance();
    if !(r.max_t <= r.critical) {
        dump(&format!("{name}-a"), &a.mean);
        dump(&format!("{name}-b"), &b.mean);
        panic!(
            "{name}: a block differs beyond its variance: {r:?}, mean luminance {ma} vs {mb} (images in {})",
            output_dir().display()
        );
    }
    eprintln!("{name}: {r:?}, mean luminance {ma:.5} vs {mb:.5}");
}

/// Result of comparing two estimates over pixel blocks.
#[derive(Debug)]
pub struct Agreement {
    /// Mean over blocks and channels of (A − B)² / (σ²_A + σ²_B).
    pub ratio: f64,
    /// Number of (block, channel) terms.
    pub terms: usize,
    /// Expected value of the ratio under agreement (variance estimated from K batches).
    pub expected: f64,
    /// Bound: expected + 6 standard deviations of the mean ratio.
    pub bound: f64,
    /// Relative difference of the mean luminance.
    pub mean_rel_diff: f64,
}

/// Compares two estimates block by block (`block`×`block` pixels).
pub fn agreement(a: &Estimate, b: &Estimate, block: u32) -> Agreement {
    let (w, h) = (a.mean.width, a.mean.height);
    assert_eq!((w, h), (b.mean.width, b.mean.height));
    let mut sum = 0.0f64;
    let mut terms = 0usize;
    for by in 0..h / block {
        for bx in 0..w / block {
            let mut da = Vec3::ZERO;
            let mut db = Vec3::ZERO;
            let mut va = Vec3::ZERO;
            let mut vb = Vec3::ZERO;
            for y in by * block..(by + 1) * block {
                for x in bx * block..(bx + 1) * block {
                    let i = (y * w + x) as usize;
                    da += a.mean.data[i];
                    db += b.mean.data[i];
                    va += a.var_of_mean[i];
                    vb += b.var_of_mean[i];
                }
            }
            for c in 0..3 {
                let v = (va[c] + vb[c]) as f64;
                let d = (da[c] - db[c]) as f64;
                if v <= 1e-20 {
                    // Both noiseless here (e.g. black): they must agree exactly up to rounding.
                    assert!(
                        d.abs() <= 1e-4 * (da[c].abs() + db[c].abs()) as f64 + 1e-9,
                        "noiseless block differs: {d}"
                    );
                    continue;
                }
                sum += d * d / v;
                terms += 1;
                if std::env::var("MIRAGE_DEBUG_AGREE").is_ok() && d * d / v > 16.0 {
                    eprintln!("block ({bx},{by}) ch {c}: a {} b {} z² {:.1}", da[c], db[c], d * d / v);
                }
            }
        }
    }
    // With variances estimated from K batches each, (A−B)²/(σ̂²_A+σ̂²_B) is roughly F(1, 2(K−1))
    // distributed: mean ν/(ν−2), variance 2ν²(ν−1)/((ν−2)²(ν−4)) with ν = 2(K−1).
    let nu = (a.batches.min(b.batches) as f64 - 1.0) * 2.0;
    let expected = nu / (nu - 2.0);
    let var_one = 2.0 * nu * nu * (nu - 1.0) / ((nu - 2.0).powi(2) * (nu - 4.0));
    let bound = expected + 6.0 * (var_one / terms.max(1) as f64).sqrt();
    let ma = a.mean.mean_luminance();
    let mb = b.mean.mean_luminance();
    Agreement { ratio: sum / terms.max(1) as f64, terms, expected, bound, mean_rel_diff: (ma - mb) / mb.max(1e-30) }
}

/// Where failing tests leave their images.
pub fn output_dir() -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("test-output");
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Writes images for inspection after a failure.
pub fn dump(name: &str, img: &Image) {
    let p = output_dir().join(format!("{name}.exr"));
    output::write_exr(&p, img, Default::default()).unwrap();
    output::write_png(&p.with_extension("png"), img, mirage::film::Tonemap::Reinhard).unwrap();
}

/// Asserts agreement, dumping both images on failure.
pub fn assert_agree(name: &str, a: &Estimate, b: &Estimate, block: u32) {
    let r = agreement(a, b, block);
    if !(r.ratio <= r.bound) || !r.ratio.is_finite() {
        dump(&format!("{name}-a"), &a.mean);
        dump(&format!("{name}-b"), &b.mean);
        panic!("{name}: images disagree beyond their variance: {r:?} (images in {})", output_dir().display());
    }
    eprintln!("{name}: {r:?}");
}
