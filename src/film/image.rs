//! A linear RGB image and the error metrics every comparison in mirage uses.

use glam::Vec3;

use crate::color::luminance;

/// A linear HDR RGB image, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixels.
    pub data: Vec<Vec3>,
}

/// Errors between two images.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageErrors {
    /// Mean over pixels and channels of (x − r)².
    pub mse: f64,
    /// Mean over pixels and channels of (x − r)² / (r² + 0.01).
    pub rel_mse: f64,
    /// MSE divided by the square of the reference's mean luminance m: the mean of (x − r)² / m².
    /// Unlike `rel_mse` it does not change with exposure (on dark scenes 0.01 dominates r² and
    /// `rel_mse` is an absolute error), and unlike a per-pixel (x − r)² / (r² + ε·m²) it divides
    /// by nothing noisy: a noisy reference adds the same Var(r)/m² to every method's value, so it
    /// still ranks them (dividing by a noisy r² penalises the method that is bright where the
    /// reference has a dark noise pixel).
    pub nmse: f64,
    /// Mean of x minus mean of r (luminance), relative to mean of r.
    pub mean_bias: f64,
}

impl Image {
    /// A black image.
    pub fn new(width: u32, height: u32) -> Self {
        Image { width, height, data: vec![Vec3::ZERO; width as usize * height as usize] }
    }

    /// Pixel at (x, y).
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.data[(y * self.width + x) as usize]
    }

    /// Mean RGB over all pixels.
    pub fn mean(&self) -> Vec3 {
        let s = self.data.iter().fold([0.0f64; 3], |a, p| [a[0] + p.x as f64, a[1] + p.y as f64, a[2] + p.z as f64]);
        let n = self.data.len().max(1) as f64;
        Vec3::new((s[0] / n) as f32, (s[1] / n) as f32, (s[2] / n) as f32)
    }

    /// Mean luminance.
    pub fn mean_luminance(&self) -> f64 {
        self.data.iter().map(|&p| luminance(p) as f64).sum::<f64>() / self.data.len().max(1) as f64
    }

    /// Number of pixels with a NaN or infinite channel.
    pub fn non_finite_count(&self) -> usize {
        self.data.iter().filter(|p| !p.is_finite()).count()
    }

    /// Errors of `self` against the reference `r` (same size).
    pub fn errors(&self, r: &Image) -> ImageErrors {
        assert_eq!((self.width, self.height), (r.width, r.height), "image sizes differ");
        let mut se = 0.0f64;
        let mut rel = 0.0f64;
        let mr = r.mean_luminance();
        for (x, r) in self.data.iter().zip(&r.data) {
            for c in 0..3 {
                let (xv, rv) = (x[c] as f64, r[c] as f64);
                let d2 = (xv - rv) * (xv - rv);
                se += d2;
                rel += d2 / (rv * rv + 0.01);
            }
        }
        let n = (self.data.len() * 3).max(1) as f64;
        let mean_bias = if mr > 0.0 { (self.mean_luminance() - mr) / mr } else { self.mean_luminance() };
        let nmse = if mr > 0.0 { se / n / (mr * mr) } else { se / n };
        ImageErrors { mse: se / n, rel_mse: rel / n, nmse, mean_bias }
    }

    /// The image scaled by `s`.
    pub fn scaled(&self, s: f32) -> Image {
        Image { width: self.width, height: self.height, data: self.data.iter().map(|p| *p * s).collect() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rel_mse_follows_its_definition() {
        let r = Image { width: 2, height: 1, data: vec![Vec3::splat(1.0), Vec3::ZERO] };
        let x = Image { width: 2, height: 1, data: vec![Vec3::splat(2.0), Vec3::splat(0.1)] };
        let e = x.errors(&r);
        let expected = (3.0 * (1.0 / 1.01) + 3.0 * (0.01 / 0.01)) / 6.0;
        assert!((e.rel_mse - expected).abs() < 1e-6);
        assert!((e.mse - (3.0 + 0.03) / 6.0).abs() < 1e-6);
        assert_eq!(x.errors(&x).rel_mse, 0.0);
    }

    #[test]
    fn nmse_does_not_change_with_exposure() {
        let r = Image { width: 3, height: 1, data: vec![Vec3::new(0.02, 0.01, 0.0), Vec3::splat(0.001), Vec3::ZERO] };
        let x = Image {
            width: 3,
            height: 1,
            data: vec![Vec3::new(0.03, 0.01, 0.002), Vec3::splat(0.0), Vec3::splat(0.004)],
        };
        let e = x.errors(&r);
        let m = r.mean_luminance();
        assert!((e.nmse - e.mse / (m * m)).abs() < 1e-9 * e.nmse, "{e:?}");
        for s in [1e-3f32, 7.0, 1e3] {
            let es = x.scaled(s).errors(&r.scaled(s));
            assert!((es.nmse / e.nmse - 1.0).abs() < 1e-4, "scale {s}: {es:?}");
        }
        // The plain relMSE of this dark image is nearly an absolute error and moves with exposure.
        assert!(x.scaled(100.0).errors(&r.scaled(100.0)).rel_mse > 100.0 * e.rel_mse);
    }
}
