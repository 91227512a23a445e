//! Display transforms: HDR linear RGB → 8-bit sRGB. The same operators, with the same numbers,
//! make `render`'s PNG, the window and `view --record`'s frames (the window's copy in
//! `view::present` is eight pixels at a time and smooths the exposure between frames).
//!
//! * **Filmic** (the default): an exposure chosen from the image — the median luminance of the
//!   lit pixels mapped to [`FILMIC_KEY`] (mid grey), times 2^stops — then Narkowicz's fit of the
//!   ACES reference rendering transform (Narkowicz 2016) applied to each pixel's largest channel,
//!   the pixel's RGB scaled by the same factor. Scaling all three channels alike keeps the
//!   linear image's chromaticity (hue and saturation) exactly and never clips one channel alone;
//!   the curve's toe and shoulder keep shadows and highlights apart (an emitter several stops
//!   above mid grey reaches white). The median, unlike a log-average, is not pulled down by black
//!   background or shadowed pixels.
//! * **Reinhard**'s global photographic operator (Reinhard et al. 2002, eq. 4): luminance scaled
//!   to key 0.18 by the log-average, compressed by L(1 + L/L_white²)/(1 + L), L_white = the
//!   largest scaled luminance, RGB scaled by the luminance ratio (channels above 1 clip).
//! * **Exposure**: multiply by 2^stops, clamp, sRGB-encode.

use glam::Vec3;

use super::Image;
use crate::color::{linear_to_srgb, luminance};

/// How HDR values become display values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Tonemap {
    /// Exposure from the image's median lit luminance plus this many stops, then the ACES
    /// fitted curve on the largest channel.
    Filmic(f32),
    /// Reinhard et al. 2002 global operator with key 0.18.
    Reinhard,
    /// Linear scaling by 2^stops, then clamp and sRGB.
    Exposure(f32),
}

impl Default for Tonemap {
    fn default() -> Self {
        Tonemap::Filmic(0.0)
    }
}

/// The display value the filmic exposure gives the median lit luminance (mid grey).
pub const FILMIC_KEY: f32 = 0.18;

/// Pixels the automatic exposure looks at, at most (every k-th pixel of larger images).
const EXPOSURE_SAMPLES: usize = 1 << 14;

/// Narkowicz's fit of the ACES RRT + ODT: x(2.51x + 0.03) / (x(2.43x + 0.59) + 0.14), clamped to
/// [0, 1]. Slope ≈ 0.2 at 0 (a toe), mid grey 0.18 → 0.27, 1 → 0.80, 7.25 and above → 1.
#[inline]
pub fn filmic_curve(x: f32) -> f32 {
    ((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)).clamp(0.0, 1.0)
}

/// The automatic exposure of the filmic operator: the factor that maps the median luminance of
/// the finite, non-black pixels to [`FILMIC_KEY`]; 1 for an image with no lit pixel. Images over
/// 16384 pixels are sampled at every k-th pixel (a median of 16k samples is within about 1 % of
/// the whole image's, and costs the window a fraction of a millisecond).
pub fn auto_exposure(data: &[Vec3]) -> f32 {
    let stride = (data.len() / EXPOSURE_SAMPLES).max(1);
    let mut lum: Vec<f32> =
        data.iter().step_by(stride).map(|&p| luminance(sanitize(p))).filter(|&l| l > 0.0 && l.is_finite()).collect();
    if lum.is_empty() {
        return 1.0;
    }
    let mid = lum.len() / 2;
    let (_, median, _) = lum.select_nth_unstable_by(mid, f32::total_cmp);
    let s = FILMIC_KEY / *median;
    if s.is_finite() && s > 0.0 { s } else { 1.0 }
}

/// The factor the filmic operator multiplies a pixel (already multiplied by the exposure) by,
/// given its largest channel `m`: curve(m) / m, 0 for m ≤ 0.
#[inline]
pub fn filmic_gain(m: f32) -> f32 {
    if m > 0.0 { filmic_curve(m) / m } else { 0.0 }
}

/// Maps an image to 8-bit sRGB, RGB interleaved.
pub fn to_srgb8(img: &Image, tm: Tonemap) -> Vec<u8> {
    let mapped: Vec<Vec3> = match tm {
        Tonemap::Exposure(stops) => {
            let s = 2f32.powf(stops);
            img.data.iter().map(|&p| sanitize(p) * s).collect()
        }
        Tonemap::Filmic(stops) => {
            let s = auto_exposure(&img.data) * 2f32.powf(stops);
            img.data
                .iter()
                .map(|&p| {
                    let p = sanitize(p) * s;
                    p * filmic_gain(p.max_element())
                })
                .collect()
        }
        Tonemap::Reinhard => {
            let lum: Vec<f32> = img.data.iter().map(|&p| luminance(sanitize(p))).collect();
            let n = lum.len().max(1) as f64;
            let log_avg = (lum.iter().map(|&l| (1e-6 + l as f64).ln()).sum::<f64>() / n).exp() as f32;
            let scale = 0.18 / log_avg.max(1e-12);
            let l_white = lum.iter().fold(0.0f32, |m, &l| m.max(l * scale)).max(1e-6);
            img.data
                .iter()
                .zip(&lum)
                .map(|(&p, &l)| {
                    if l <= 0.0 {
                        return Vec3::ZERO;
                    }
                    let ls = l * scale;
                    let ld = ls * (1.0 + ls / (l_white * l_white)) / (1.0 + ls);
                    sanitize(p) * (ld / l)
                })
                .collect()
        }
    };
    let mut out = Vec::with_capacity(mapped.len() * 3);
    for p in mapped {
        for c in [p.x, p.y, p.z] {
            out.push((linear_to_srgb(c) * 255.0 + 0.5) as u8);
        }
    }
    out
}

fn sanitize(p: Vec3) -> Vec3 {
    if p.is_finite() { p.max(Vec3::ZERO) } else { Vec3::ZERO }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_filmic_curve_is_monotone_with_a_toe_and_a_shoulder() {
        let mut last = 0.0;
        for i in 1..=2000 {
            let x = i as f32 * 0.01;
            let y = filmic_curve(x);
            assert!(y >= last && y <= 1.0, "x {x}: {y} after {last}");
            last = y;
        }
        assert_eq!(filmic_curve(0.0), 0.0);
        assert!((filmic_curve(FILMIC_KEY) - 0.267).abs() < 0.01);
        assert!(filmic_curve(1.0) < 0.81 && filmic_curve(1.0) > 0.79);
        assert_eq!(filmic_curve(12.0), 1.0);
    }

    /// The exposure puts the median lit pixel at mid grey, whatever the image's scale and however
    /// many black pixels it has; the mapped pixels keep their channel ratios.
    #[test]
    fn filmic_exposure_follows_the_median_and_keeps_channel_ratios() {
        let mut data: Vec<Vec3> = (0..999).map(|i| Vec3::new(0.5, 0.25, 0.05) * (1.0 + i as f32 / 100.0)).collect();
        data.extend(std::iter::repeat_n(Vec3::ZERO, 3000));
        data.push(Vec3::NAN);
        let median = luminance(Vec3::new(0.5, 0.25, 0.05) * (1.0 + 499.0 / 100.0));
        for scale in [1e-4f32, 1.0, 1e3] {
            let scaled: Vec<Vec3> = data.iter().map(|&p| p * scale).collect();
            let s = auto_exposure(&scaled);
            assert!((s * median * scale / FILMIC_KEY - 1.0).abs() < 1e-4, "scale {scale}: {s}");
        }
        assert_eq!(auto_exposure(&[Vec3::ZERO, Vec3::NAN]), 1.0);
        let img = Image { width: 8, height: 1, data: data[..8].to_vec() };
        let px = to_srgb8(&img, Tonemap::Filmic(0.0));
        // Decoded back to linear, red : green stays 2 : 1 up to 8-bit rounding.
        let lin = |v: u8| crate::color::srgb_to_linear(v as f32 / 255.0);
        for p in px.chunks(3) {
            assert!((lin(p[0]) / lin(p[1]) - 2.0).abs() < 0.05, "{p:?}");
        }
    }
}
