//! Display transforms: HDR linear RGB → 8-bit sRGB.
//!
//! * Reinhard's global photographic operator (Reinhard et al. 2002, eq. 4; papers/000 footnote
//!   10): luminance scaled to key 0.18 by the log-average, compressed by L(1 + L/L_white²)/(1 + L),
//!   L_white = the largest scaled luminance, colour kept by scaling RGB with the luminance ratio.
//! * Exposure: multiply by 2^stops, clamp, sRGB-encode.

use glam::Vec3;

use super::Image;
use crate::color::{linear_to_srgb, luminance};

/// How HDR values become display values.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum Tonemap {
    /// Reinhard et al. 2002 global operator with key 0.18.
    #[default]
    Reinhard,
    /// Linear scaling by 2^stops, then clamp and sRGB.
    Exposure(f32),
}

/// Maps an image to 8-bit sRGB, RGB interleaved.
pub fn to_srgb8(img: &Image, tm: Tonemap) -> Vec<u8> {
    let mapped: Vec<Vec3> = match tm {
        Tonemap::Exposure(stops) => {
            let s = 2f32.powf(stops);
            img.data.iter().map(|&p| sanitize(p) * s).collect()
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
