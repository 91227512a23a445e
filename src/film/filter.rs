//! Pixel reconstruction filters, importance-sampled (pbrt-v4 §5.4.3 / §8.8): each camera sample
//! is placed at an offset drawn ∝ |f| and carries weight f/p, so a sample only ever contributes
//! to its own pixel. Tiles then never overlap and images are identical at any thread count.

use std::f32::consts::PI;

use glam::{Vec2, vec2};

use crate::sampling::Distribution1D;

/// The reconstruction filter kinds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum FilterKind {
    /// Box of radius 0.5 (each pixel averages the radiance through its own square).
    #[default]
    Box,
    /// Tent (triangle) of radius 1.
    Tent,
    /// Gaussian, σ = 0.5, radius 1.5.
    Gaussian,
    /// Mitchell–Netravali (B = C = 1/3), radius 2.
    Mitchell,
    /// Lanczos-windowed sinc with a = 2: sinc(x)·sinc(x/2) on |x| < 2.
    Lanczos,
}

impl FilterKind {
    /// Every kind, for listings.
    pub const ALL: [FilterKind; 5] =
        [FilterKind::Box, FilterKind::Tent, FilterKind::Gaussian, FilterKind::Mitchell, FilterKind::Lanczos];

    /// Support radius in pixels.
    pub fn radius(self) -> f32 {
        match self {
            FilterKind::Box => 0.5,
            FilterKind::Tent => 1.0,
            FilterKind::Gaussian => 1.5,
            FilterKind::Mitchell | FilterKind::Lanczos => 2.0,
        }
    }

    /// The 1D profile; the 2D filter is separable: f(x, y) = f1(x) f1(y).
    pub fn eval_1d(self, x: f32) -> f32 {
        let r = self.radius();
        let ax = x.abs();
        if ax > r {
            return 0.0;
        }
        match self {
            FilterKind::Box => 1.0,
            FilterKind::Tent => 1.0 - ax,
            FilterKind::Gaussian => {
                let g = |v: f32| (-v * v / (2.0 * 0.25)).exp();
                (g(ax) - g(r)).max(0.0)
            }
            FilterKind::Mitchell => {
                let (b, c) = (1.0 / 3.0, 1.0 / 3.0);
                let t = ax; // profile defined on [0, 2]
                if t < 1.0 {
                    ((12.0 - 9.0 * b - 6.0 * c) * t * t * t + (-18.0 + 12.0 * b + 6.0 * c) * t * t + (6.0 - 2.0 * b))
                        / 6.0
                } else {
                    ((-b - 6.0 * c) * t * t * t
                        + (6.0 * b + 30.0 * c) * t * t
                        + (-12.0 * b - 48.0 * c) * t
                        + (8.0 * b + 24.0 * c))
                        / 6.0
                }
            }
            FilterKind::Lanczos => {
                let sinc = |v: f32| if v.abs() < 1e-5 { 1.0 } else { (PI * v).sin() / (PI * v) };
                sinc(ax) * sinc(ax / r)
            }
        }
    }
}

/// A filter with its sampling table.
#[derive(Clone, Debug)]
pub struct PixelFilter {
    /// Which filter.
    pub kind: FilterKind,
    table: Distribution1D,
    signs: Vec<f32>,
    bins: usize,
}

/// A sampled film offset with its weight f/p.
#[derive(Clone, Copy, Debug)]
pub struct FilterSample {
    /// Offset from the pixel centre, in pixels.
    pub offset: Vec2,
    /// Weight f(offset) / p(offset).
    pub weight: f32,
}

impl PixelFilter {
    /// Tabulates `kind` for sampling.
    pub fn new(kind: FilterKind) -> Self {
        let bins = 256;
        let r = kind.radius();
        let values: Vec<f32> = (0..bins).map(|i| kind.eval_1d(-r + (i as f32 + 0.5) / bins as f32 * 2.0 * r)).collect();
        let weights: Vec<f64> = values.iter().map(|v| v.abs() as f64).collect();
        let table = Distribution1D::new(&weights).expect("filter profiles are non-zero");
        let signs = values.iter().map(|v| if *v < 0.0 { -1.0 } else { 1.0 }).collect();
        PixelFilter { kind, table, signs, bins }
    }

    fn sample_1d(&self, u: f32) -> (f32, f32) {
        let r = self.kind.radius();
        if self.kind == FilterKind::Box {
            return (-r + u * 2.0 * r, 1.0);
        }
        let s = self.table.sample(u);
        let x = -r + (s.index as f32 + s.u_remapped) / self.bins as f32 * 2.0 * r;
        (x, self.signs[s.index])
    }

    /// Draws an offset ∝ |f|; the weight is ±1 (the common normalisation cancels in the
    /// weighted mean Σ w L / Σ w).
    pub fn sample(&self, u: Vec2) -> FilterSample {
        let (x, sx) = self.sample_1d(u.x);
        let (y, sy) = self.sample_1d(u.y);
        FilterSample { offset: vec2(x, y), weight: sx * sy }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filters_peak_at_the_centre_and_vanish_outside_their_radius() {
        for k in FilterKind::ALL {
            assert!(k.eval_1d(0.0) > 0.0, "{k:?}");
            assert_eq!(k.eval_1d(k.radius() + 0.01), 0.0, "{k:?}");
            assert!(k.eval_1d(0.0) >= k.eval_1d(0.4), "{k:?}");
        }
        // Mitchell and Lanczos have negative lobes.
        assert!(FilterKind::Mitchell.eval_1d(1.5) < 0.0);
        assert!(FilterKind::Lanczos.eval_1d(1.5) < 0.0);
    }

    #[test]
    fn sampled_offsets_stay_inside_the_support() {
        for k in FilterKind::ALL {
            let f = PixelFilter::new(k);
            for i in 0..100 {
                let u = vec2(i as f32 / 100.0, 1.0 - i as f32 / 100.0 - 1e-4);
                let s = f.sample(u);
                assert!(s.offset.abs().max_element() <= k.radius() + 1e-4);
                assert!(s.weight.abs() == 1.0);
            }
        }
    }
}
