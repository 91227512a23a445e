//! From the accumulated linear image to window pixels: tone mapping into 0x00RRGGBB words
//! (softbuffer's format), nearest-neighbour upscaling from the render resolution (`--scale`) to
//! the window, and screenshots (linear EXR + the PNG exactly as displayed).
//!
//! The operators are those of [`crate::film::tonemap`] (filmic, Reinhard et al. 2002 global
//! operator with key 0.18, or a linear exposure), made cheap enough for every frame: image
//! statistics are taken over a strided subset of at most 64k pixels, eight pixels are mapped at a
//! time, and the sRGB encoding is a table lookup. The frame loop resolves the filmic operator's
//! exposure per frame ([`Mapping::Filmic`]), smoothing it between frames.

use std::path::Path;
use std::sync::OnceLock;

use glam::Vec3;
use rayon::prelude::*;

use crate::color::{linear_to_srgb, luminance};
use crate::film::Image;
pub use crate::film::tonemap::auto_exposure;
use crate::output::{self, Aovs, SaveError};
use crate::simd::{F8, Lanes};

/// How one frame maps radiance to display values (a [`crate::film::Tonemap`] with its exposure
/// resolved).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Mapping {
    /// Multiply by `scale`, then the filmic curve on the largest channel
    /// ([`crate::film::tonemap::filmic_gain`]).
    Filmic {
        /// Exposure factor.
        scale: f32,
    },
    /// Reinhard's global operator, key 0.18, white point = the brightest pixel.
    Reinhard,
    /// Multiply by `scale` and clamp.
    Linear {
        /// Exposure factor.
        scale: f32,
    },
}

impl Mapping {
    /// The mapping `film::to_srgb8` applies to a still image with `tonemap`.
    pub fn of_still(tonemap: crate::film::Tonemap, image: &[Vec3]) -> Mapping {
        use crate::film::Tonemap;
        match tonemap {
            Tonemap::Filmic(stops) => Mapping::Filmic { scale: auto_exposure(image) * 2f32.powf(stops) },
            Tonemap::Reinhard => Mapping::Reinhard,
            Tonemap::Exposure(stops) => Mapping::Linear { scale: 2f32.powf(stops) },
        }
    }
}

/// Entries of the linear → sRGB table on [0, 1].
const LUT_SIZE: usize = 1 << 14;

fn srgb_lut() -> &'static [u8] {
    static LUT: OnceLock<Vec<u8>> = OnceLock::new();
    LUT.get_or_init(|| {
        (0..LUT_SIZE).map(|i| (linear_to_srgb(i as f32 / (LUT_SIZE - 1) as f32) * 255.0 + 0.5) as u8).collect()
    })
}

#[inline]
fn sanitize(p: Vec3) -> Vec3 {
    if p.is_finite() { p.max(Vec3::ZERO) } else { Vec3::ZERO }
}

/// Reinhard's image statistics: (scale = key 0.18 / log-average luminance, white = brightest
/// scaled luminance).
fn reinhard_stats(image: &[Vec3]) -> (f32, f32) {
    let stride = (image.len() / 65_536).max(1);
    // The log-average over every stride-th pixel, eight at a time: the per-pixel libm logarithm
    // took 0.4 ms of a 512² frame's 1.1 ms tone map.
    let sampled = image.len().div_ceil(stride);
    let (sum, n) = (0..sampled.div_ceil(F8::LANES))
        .into_par_iter()
        .with_min_len(256)
        .map(|b| {
            let first = b * F8::LANES;
            let lanes = (sampled - first).min(F8::LANES);
            let px: [Vec3; 8] =
                std::array::from_fn(|i| if i < lanes { image[(first + i) * stride] } else { Vec3::ZERO });
            let log = (F8::splat(1e-6) + luminance8(&sanitized8(&px[..lanes]))).ln().to_array();
            (log[..lanes].iter().map(|&l| l as f64).sum::<f64>(), lanes)
        })
        .reduce(|| (0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    let log_avg = (sum / n.max(1) as f64).exp() as f32;
    let scale = 0.18 / log_avg.max(1e-12);
    let max_lum = image.par_iter().map(|&p| luminance(sanitize(p))).reduce(|| 0.0, f32::max);
    (scale, (max_lum * scale).max(1e-6))
}

/// Up to eight pixels as channel lanes, sanitised as [`sanitize`] does (missing pixels black).
#[inline(always)]
fn sanitized8(px: &[Vec3]) -> [F8; 3] {
    let zero = F8::splat(0.0);
    let channel = |k: usize| F8::from_fn(|i| px.get(i).map_or(0.0, |p| p[k]));
    let c = [channel(0), channel(1), channel(2)];
    let finite = c[0].finite().and(c[1].finite()).and(c[2].finite());
    c.map(|c| finite.select(c.vmax(zero), zero))
}

/// [`luminance`] on eight lanes, the same operations in the same order.
#[inline(always)]
fn luminance8(c: &[F8; 3]) -> F8 {
    F8::splat(0.2126) * c[0] + F8::splat(0.7152) * c[1] + F8::splat(0.0722) * c[2]
}

/// Tone-maps `image` into `out` (same length), one 0x00RRGGBB word per pixel.
pub fn tonemap(image: &[Vec3], mapping: Mapping, out: &mut [u32]) {
    assert_eq!(image.len(), out.len(), "tone-map buffers differ in size");
    let zero = F8::splat(0.0);
    match mapping {
        Mapping::Linear { scale } => {
            let s = F8::splat(scale);
            encode_scaled(image, out, |_| s);
        }
        Mapping::Filmic { scale } => {
            let s = F8::splat(scale);
            let [a, b, c, d, e] = [2.51, 0.03, 2.43, 0.59, 0.14].map(F8::splat);
            encode_scaled(image, out, |ch| {
                // filmic_gain(m) · scale with m = scale · max channel: curve(m) / m, the curve
                // as `film::tonemap::filmic_curve` writes it; black where m ≤ 0.
                let m = ch[0].vmax(ch[1]).vmax(ch[2]) * s;
                let curve = ((m * (a * m + b)) / (m * (c * m + d) + e)).vmax(zero).vmin(F8::splat(1.0));
                m.le(zero).select(zero, curve / m * s)
            });
        }
        Mapping::Reinhard => {
            let (scale, white) = reinhard_stats(image);
            let (one, scale, inv_white2) = (F8::splat(1.0), F8::splat(scale), F8::splat(1.0 / (white * white)));
            encode_scaled(image, out, |ch| {
                // L_d / L with L_s = scale·L: scale·(1 + L_s / L_white²) / (1 + L_s); black
                // where L_s ≤ 0.
                let ls = luminance8(ch) * scale;
                ls.le(zero).select(zero, scale * (one + ls * inv_white2) / (one + ls))
            });
        }
    }
}

/// Encodes each pixel of `image`, sanitised (non-finite → black, negative channels → 0) and
/// multiplied by `gain` of its channels, into `out` through the sRGB table: eight pixels at a
/// time, with the per-pixel form's operations in the same order ([`luminance`], then
/// `(v · (LUT_SIZE − 1) + 0.5)` truncated and clamped), so the same words (tested). A third of the
/// per-pixel form's time: per pixel it was a division, three saturating conversions and branches.
fn encode_scaled(image: &[Vec3], out: &mut [u32], gain: impl Fn(&[F8; 3]) -> F8 + Sync) {
    let lut = srgb_lut();
    let (half, top) = (F8::splat(0.5), F8::splat((LUT_SIZE - 1) as f32));
    out.par_chunks_mut(4096).zip(image.par_chunks(4096)).for_each(|(out, image)| {
        for (o, px) in out.chunks_mut(F8::LANES).zip(image.chunks(F8::LANES)) {
            let c = sanitized8(px);
            let g = gain(&c);
            // Table indices: the values are ≥ 0 and not NaN here, so clamping before the
            // truncation equals the scalar truncation followed by the clamp.
            let index = c.map(|c| ((c * g) * top + half).vmin(top).trunc_int().to_array());
            for (i, o) in o.iter_mut().enumerate() {
                let e = |k: usize| lut[index[k][i] as usize] as u32;
                *o = (e(0) << 16) | (e(1) << 8) | e(2);
            }
        }
    });
}

/// Copies a `sw`×`sh` image into a `dw`×`dh` one, nearest neighbour (upscaling or downscaling).
pub fn resample_nearest(src: &[u32], sw: u32, sh: u32, dst: &mut [u32], dw: u32, dh: u32) {
    assert_eq!(src.len(), (sw * sh) as usize);
    assert_eq!(dst.len(), (dw * dh) as usize);
    if (sw, sh) == (dw, dh) {
        dst.copy_from_slice(src);
        return;
    }
    let xs: Vec<usize> = (0..dw).map(|x| ((x as u64 * sw as u64 / dw as u64) as usize).min(sw as usize - 1)).collect();
    dst.par_chunks_mut(dw as usize).enumerate().for_each(|(y, row)| {
        let sy = ((y as u64 * sh as u64 / dh as u64) as usize).min(sh as usize - 1);
        let line = &src[sy * sw as usize..(sy + 1) * sw as usize];
        for (o, &sx) in row.iter_mut().zip(&xs) {
            *o = line[sx];
        }
    });
}

/// Writes the displayed pixels (0x00RRGGBB) as an 8-bit PNG.
pub fn write_png_rgb(path: &Path, pixels: &[u32], width: u32, height: u32) -> Result<(), SaveError> {
    let bytes: Vec<u8> = pixels.iter().flat_map(|&p| [(p >> 16) as u8, (p >> 8) as u8, p as u8]).collect();
    image::save_buffer(path, &bytes, width, height, image::ColorType::Rgb8)
        .map_err(|e| SaveError { path: path.to_path_buf(), message: format!("cannot write PNG: {e}") })
}

/// Writes a screenshot: the linear image as EXR at `png` with extension `.exr`, and the
/// displayed pixels as the PNG.
pub fn screenshot(png: &Path, linear: &[Vec3], displayed: &[u32], width: u32, height: u32) -> Result<(), SaveError> {
    if let Some(dir) = png.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .map_err(|e| SaveError { path: dir.to_path_buf(), message: format!("cannot create directory: {e}") })?;
    }
    let img = Image { width, height, data: linear.to_vec() };
    output::write_exr(&png.with_extension("exr"), &img, Aovs::default())?;
    write_png_rgb(png, displayed, width, height)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::tonemap::filmic_gain;
    use crate::film::{Tonemap, to_srgb8};

    #[test]
    fn window_tone_mapping_matches_the_film_operator() {
        let data: Vec<Vec3> = (0..4096)
            .map(|i| {
                let t = i as f32 / 4096.0;
                Vec3::new(t * 3.0, (t * 7.0).fract(), 0.01 + t * t * 20.0)
            })
            .collect();
        let img = Image { width: 64, height: 64, data: data.clone() };
        for tm in [Tonemap::Filmic(0.0), Tonemap::Filmic(-1.3), Tonemap::Reinhard, Tonemap::Exposure(-1.5)] {
            let curve = Mapping::of_still(tm, &data);
            let mut out = vec![0u32; data.len()];
            tonemap(&data, curve, &mut out);
            let film = to_srgb8(&img, tm);
            for (i, &p) in out.iter().enumerate() {
                let ours = [(p >> 16) as u8, (p >> 8) as u8, p as u8];
                for c in 0..3 {
                    let d = (ours[c] as i32 - film[3 * i + c] as i32).abs();
                    assert!(d <= 1, "{curve:?} pixel {i} channel {c}: {ours:?} vs film");
                }
            }
        }
    }

    /// The eight-pixel encoder gives the words of the per-pixel form it replaced, on an image
    /// whose length is not a multiple of eight, with non-finite, negative, subnormal and huge
    /// channels.
    #[test]
    fn eight_pixel_encoding_equals_the_per_pixel_form() {
        let encode = |lut: &[u8], v: f32| {
            let i = (v * (LUT_SIZE - 1) as f32 + 0.5) as usize;
            lut[i.min(LUT_SIZE - 1)] as u32
        };
        let lut = srgb_lut();
        let pack = |c: Vec3| (encode(lut, c.x) << 16) | (encode(lut, c.y) << 8) | encode(lut, c.z);
        let odd = [f32::NAN, f32::INFINITY, -2.0, 1e-45, 1e30, 0.0, -0.0];
        let data: Vec<Vec3> = (0..1003)
            .map(|i| {
                let t = (i as f32 * 0.618).fract();
                let c = Vec3::new(t * 4.0, (t * 13.0).fract() * 0.3, t * t);
                if i % 17 == 0 { Vec3::new(c.x, odd[(i / 17) % odd.len()], c.z) } else { c }
            })
            .collect();
        let (scale, white) = reinhard_stats(&data);
        let inv_white2 = 1.0 / (white * white);
        let reinhard = |p: Vec3| {
            let p = sanitize(p);
            let ls = luminance(p) * scale;
            if ls <= 0.0 { 0 } else { pack(p * (scale * (1.0 + ls * inv_white2) / (1.0 + ls))) }
        };
        let s = 2f32.powf(0.7);
        let exposure = |p: Vec3| pack(sanitize(p) * s);
        let filmic = |p: Vec3| {
            let q = sanitize(p);
            pack(q * (filmic_gain(q.max_element() * s) * s))
        };
        for (curve, per_pixel) in [
            (Mapping::Reinhard, &reinhard as &dyn Fn(Vec3) -> u32),
            (Mapping::Linear { scale: s }, &exposure),
            (Mapping::Filmic { scale: s }, &filmic),
        ] {
            let mut out = vec![0u32; data.len()];
            tonemap(&data, curve, &mut out);
            for (i, (&o, &p)) in out.iter().zip(&data).enumerate() {
                assert_eq!(o, per_pixel(p), "{curve:?} pixel {i} {p}");
            }
        }
    }

    /// The eight-lane log-average is the per-pixel f64 one over the same sampled pixels (every
    /// pixel, and every second one past 131072 pixels), within the f32 logarithm's error: a
    /// per-sample error of ≤ 2 ulp of |ln L| ≤ 14 moves the mean by < 4·10⁻⁶, so the scale
    /// (0.18 / exp(mean)) agrees within 10⁻⁵ relative. A wrong sample or lane misses by far more.
    #[test]
    fn eight_pixel_log_average_equals_the_per_pixel_one() {
        let odd = [f32::NAN, f32::INFINITY, -2.0, 1e-45, 30.0, 0.0];
        for len in [1usize, 7, 1003, 131_072 + 5] {
            let data: Vec<Vec3> = (0..len)
                .map(|i| {
                    let t = (i as f32 * 0.618).fract();
                    let c = Vec3::new(t * 4.0, (t * 13.0).fract() * 0.3, t * t * 0.01);
                    if i % 17 == 0 { Vec3::new(c.x, odd[(i / 17) % odd.len()], c.z) } else { c }
                })
                .collect();
            let stride = (len / 65_536).max(1);
            let logs: Vec<f64> =
                data.iter().step_by(stride).map(|&p| (1e-6 + luminance(sanitize(p)) as f64).ln()).collect();
            let scale = 0.18 / (logs.iter().sum::<f64>() / logs.len() as f64).exp();
            let (got, _) = reinhard_stats(&data);
            assert!(((got as f64 - scale) / scale).abs() < 1e-5, "{len} pixels: {got} against {scale}");
        }
    }

    #[test]
    fn non_finite_and_negative_pixels_display_black() {
        let data = [Vec3::NAN, Vec3::splat(-1.0), Vec3::splat(f32::INFINITY), Vec3::ONE];
        let mut out = [1u32; 4];
        for m in [Mapping::Reinhard, Mapping::Filmic { scale: 1.0 }, Mapping::Linear { scale: 1.0 }] {
            tonemap(&data, m, &mut out);
            assert_eq!(&out[..3], &[0, 0, 0], "{m:?}");
            assert_ne!(out[3], 0, "{m:?}");
        }
    }

    #[test]
    fn nearest_resampling_repeats_pixels() {
        let src = [1u32, 2, 3, 4];
        let mut dst = [0u32; 16];
        resample_nearest(&src, 2, 2, &mut dst, 4, 4);
        assert_eq!(dst, [1, 1, 2, 2, 1, 1, 2, 2, 3, 3, 4, 4, 3, 3, 4, 4]);
        let mut small = [0u32; 1];
        resample_nearest(&src, 2, 2, &mut small, 1, 1);
        assert_eq!(small, [1]);
    }
}
