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

/// A piecewise-constant 2D distribution over the unit square, `width` × `height` cells with
/// probability ∝ the given weights: a marginal over rows and a conditional per row (pbrt-v4
/// §A.5.6). Used to importance-sample an environment map by its luminance.
#[derive(Clone, Debug)]
pub struct Distribution2D {
    width: usize,
    height: usize,
    rows: Vec<Option<Distribution1D>>,
    marginal: Distribution1D,
}

/// One draw from a [`Distribution2D`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample2D {
    /// Point in the unit square, uniform within the chosen cell.
    pub uv: glam::Vec2,
    /// Density of `uv` with respect to area in the unit square.
    pub pdf: f32,
}

impl Distribution2D {
    /// A distribution over `width` × `height` cells (row-major weights, top row first); `None`
    /// when every weight is zero or the sizes do not match.
    pub fn new(weights: &[f64], width: usize, height: usize) -> Option<Self> {
        if width == 0 || height == 0 || weights.len() != width * height {
            return None;
        }
        let rows: Vec<Option<Distribution1D>> = weights.chunks_exact(width).map(Distribution1D::new).collect();
        let marginal =
            Distribution1D::new(&rows.iter().map(|r| r.as_ref().map_or(0.0, |r| r.total())).collect::<Vec<_>>())?;
        Some(Distribution2D { width, height, rows, marginal })
    }

    /// A point ∝ the weights.
    pub fn sample(&self, u: glam::Vec2) -> Sample2D {
        let row = self.marginal.sample(u.y);
        let cond = self.rows[row.index].as_ref().expect("the marginal never picks an empty row");
        let col = cond.sample(u.x);
        let uv = glam::Vec2::new(
            (col.index as f32 + col.u_remapped) / self.width as f32,
            (row.index as f32 + row.u_remapped) / self.height as f32,
        );
        Sample2D { uv, pdf: row.pmf * col.pmf * (self.width * self.height) as f32 }
    }

    /// Density of the point `uv` of the unit square.
    pub fn pdf(&self, uv: glam::Vec2) -> f32 {
        let x = ((uv.x * self.width as f32) as usize).min(self.width - 1);
        let y = ((uv.y * self.height as f32) as usize).min(self.height - 1);
        match &self.rows[y] {
            Some(r) => self.marginal.pmf(y) * r.pmf(x) * (self.width * self.height) as f32,
            None => 0.0,
        }
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

    /// The 2D distribution's density integrates to one over the unit square, is ∝ the weights,
    /// and its samples fall in cells with the frequencies of their weights.
    #[test]
    fn distribution_2d_density_is_normalised_and_followed_by_its_samples() {
        let (w, h) = (5usize, 3usize);
        let weights: Vec<f64> = (0..w * h).map(|i| if i % 4 == 1 { 0.0 } else { 1.0 + i as f64 }).collect();
        let d = Distribution2D::new(&weights, w, h).unwrap();
        let total: f64 = weights.iter().sum();
        let mut integral = 0.0f64;
        for y in 0..h {
            for x in 0..w {
                let uv = glam::Vec2::new((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
                let p = d.pdf(uv) as f64;
                integral += p / (w * h) as f64;
                assert!((p - weights[y * w + x] / total * (w * h) as f64).abs() < 1e-4, "cell ({x}, {y})");
            }
        }
        assert!((integral - 1.0).abs() < 1e-5, "{integral}");
        let mut r = Pcg32::new(3);
        let n = 200_000;
        let mut counts = vec![0u32; w * h];
        for _ in 0..n {
            let s = d.sample(glam::Vec2::new(r.next_f32(), r.next_f32()));
            let (x, y) = ((s.uv.x * w as f32) as usize, (s.uv.y * h as f32) as usize);
            assert!((s.pdf - d.pdf(s.uv)).abs() <= 1e-5 * s.pdf, "sample density");
            counts[y * w + x] += 1;
        }
        for (i, &c) in counts.iter().enumerate() {
            let p = weights[i] / total;
            let sd = (p * (1.0 - p) / n as f64).sqrt();
            assert!((c as f64 / n as f64 - p).abs() <= 5.0 * sd + 1e-9, "cell {i}: {c} of {n}, p {p}");
        }
    }
}
