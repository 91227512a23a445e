//! Piecewise-constant 1D distributions: choose an index ∝ a weight (emitters ∝ power, lights ∝
//! their contribution to the camera, VPL candidates ∝ weight when resampling).

/// A discrete distribution over `0..n` with probability ∝ the given non-negative weights.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    cdf: Vec<f64>,
    total: f64,
}

/// One draw from a [`Distribution1D`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiscreteSample {
    /// The chosen index.
    pub index: usize,
    /// Its probability.
    pub pmf: f32,
    /// The uniform number re-expanded to [0, 1) inside the chosen bin (for reuse).
    pub u_remapped: f32,
}

impl Distribution1D {
    /// A distribution ∝ `weights`. Negative, NaN and infinite weights count as zero. Returns
    /// `None` when all weights are zero (nothing can be sampled).
    pub fn new(weights: &[f64]) -> Option<Self> {
        let mut cdf = Vec::with_capacity(weights.len() + 1);
        let mut acc = 0.0f64;
        cdf.push(0.0);
        for &w in weights {
            if w.is_finite() && w > 0.0 {
                acc += w;
            }
            cdf.push(acc);
        }
        if acc <= 0.0 || !acc.is_finite() {
            return None;
        }
        Some(Distribution1D { cdf, total: acc })
    }

    /// Number of bins.
    pub fn len(&self) -> usize {
        self.cdf.len() - 1
    }

    /// Always false: an empty distribution cannot be built.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Sum of the weights.
    pub fn total(&self) -> f64 {
        self.total
    }

    /// Probability of choosing `index`.
    pub fn pmf(&self, index: usize) -> f32 {
        ((self.cdf[index + 1] - self.cdf[index]) / self.total) as f32
    }

    /// Chooses an index with probability ∝ its weight; never returns a zero-weight bin.
    pub fn sample(&self, u: f32) -> DiscreteSample {
        let target = (u as f64).clamp(0.0, 1.0) * self.total;
        // First bin whose upper cdf exceeds the target, skipping zero-width bins.
        let mut lo = 0usize;
        let mut hi = self.len();
        while lo < hi {
            let mid = (lo + hi) / 2;
            if self.cdf[mid + 1] <= target {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        let mut index = lo.min(self.len() - 1);
        while self.cdf[index + 1] - self.cdf[index] <= 0.0 && index > 0 {
            index -= 1;
        }
        let width = self.cdf[index + 1] - self.cdf[index];
        let u_remapped = (((target - self.cdf[index]) / width) as f32).clamp(0.0, 1.0 - f32::EPSILON);
        DiscreteSample { index, pmf: self.pmf(index), u_remapped }
    }

    /// The uniform number that [`sample`](Self::sample) maps to the start of bin `index`
    /// shifted by `u_remapped` within it.
    pub fn invert(&self, index: usize, u_remapped: f32) -> f32 {
        let width = self.cdf[index + 1] - self.cdf[index];
        ((self.cdf[index] + u_remapped as f64 * width) / self.total) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    #[test]
    fn frequencies_follow_weights_and_zero_bins_are_never_chosen() {
        let d = Distribution1D::new(&[1.0, 0.0, 3.0, 0.0]).unwrap();
        let mut r = Pcg32::new(1);
        let mut counts = [0u32; 4];
        let n = 100_000;
        for _ in 0..n {
            counts[d.sample(r.next_f32()).index] += 1;
        }
        assert_eq!(counts[1] + counts[3], 0);
        let p0 = counts[0] as f64 / n as f64;
        // binomial standard deviation sqrt(p(1-p)/n) ~ 1.4e-3; 5 sigma.
        assert!((p0 - 0.25).abs() < 0.007, "{p0}");
        assert_eq!(d.sample(0.0).index, 0);
        assert_eq!(d.sample(0.9999999).index, 2);
        assert!((d.pmf(2) - 0.75).abs() < 1e-6);
    }

    #[test]
    fn all_zero_weights_give_none() {
        assert!(Distribution1D::new(&[0.0, f64::NAN, -1.0]).is_none());
        assert!(Distribution1D::new(&[]).is_none());
    }
}
