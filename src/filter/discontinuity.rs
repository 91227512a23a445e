//! The discontinuity buffer (Wald, Kollig, Benthin, Keller & Slusallek 2002; papers/002 §7.2):
//! each pixel averages gathered / albedo over the n×m window around it, using only neighbours
//! on the same continuous surface (normals within an angle, depths within a relative tolerance),
//! then multiplies by its own albedo. With an n×m interleave pattern every window holds each VPL
//! subset once, so a pixel inside a continuous surface sees all VPLs; texture detail stays sharp
//! (it is in the albedo), and nothing leaks across edges.

use glam::Vec3;
use rayon::prelude::*;

/// Thresholds of the discontinuity buffer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiscontinuitySettings {
    /// Window width (the interleave tile width n).
    pub n: u32,
    /// Window height (the interleave tile height m).
    pub m: u32,
    /// Largest angle between neighbour normals, degrees.
    pub max_normal_angle_deg: f32,
    /// Largest relative depth difference |d − d'| / d.
    pub max_relative_depth: f32,
}

impl DiscontinuitySettings {
    /// Default thresholds for an n×m pattern: 20°, 5 %.
    pub fn new(n: u32, m: u32) -> Self {
        DiscontinuitySettings { n, m, max_normal_angle_deg: 20.0, max_relative_depth: 0.05 }
    }
}

/// Filters `gathered` (per-pixel VPL light) using the G-buffer's albedo, normals and depths.
pub fn filter(
    width: u32,
    height: u32,
    gathered: &[Vec3],
    albedo: &[Vec3],
    normal: &[Vec3],
    depth: &[f32],
    s: &DiscontinuitySettings,
) -> Vec<Vec3> {
    let cos_max = s.max_normal_angle_deg.to_radians().cos();
    let (w, h) = (width as usize, height as usize);
    let (x_lo, x_hi) = (s.n as usize / 2, (s.n as usize - 1) / 2);
    let (y_lo, y_hi) = (s.m as usize / 2, (s.m as usize - 1) / 2);
    // Irradiance-like quantity gathered / albedo, once per pixel (None: a zero albedo channel,
    // the pixel neither gives nor takes).
    let ratio: Vec<Option<Vec3>> = gathered
        .par_iter()
        .zip(albedo.par_iter())
        .map(|(g, a)| if a.min_element() <= 0.0 { None } else { Some(*g / *a) })
        .collect();
    let mut out = vec![Vec3::ZERO; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let (y0, y1) = (y.saturating_sub(y_lo), (y + y_hi).min(h - 1));
        for (x, o) in row.iter_mut().enumerate() {
            let i = y * w + x;
            let (n0, d0) = (normal[i], depth[i]);
            *o = gathered[i];
            let Some(r0) = ratio[i] else { continue };
            if n0 == Vec3::ZERO || d0 <= 0.0 {
                continue;
            }
            let tol = s.max_relative_depth * d0;
            let (x0, x1) = (x.saturating_sub(x_lo), (x + x_hi).min(w - 1));
            // The window includes the pixel itself, which always passes its own test.
            let mut sum = Vec3::ZERO;
            let mut count = 0.0f32;
            for yy in y0..=y1 {
                let r = yy * w + x0..=yy * w + x1;
                for ((n, d), q) in normal[r.clone()].iter().zip(&depth[r.clone()]).zip(&ratio[r]) {
                    if let Some(q) = q
                        && n.dot(n0) >= cos_max
                        && (d - d0).abs() <= tol
                    {
                        sum += *q;
                        count += 1.0;
                    }
                }
            }
            *o = if count > 0.0 { sum / count } else { r0 } * albedo[i];
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_surface_averages_its_window() {
        let (w, h) = (8u32, 8u32);
        let n = (w * h) as usize;
        let gathered: Vec<Vec3> = (0..n).map(|i| Vec3::splat((i % 4) as f32)).collect();
        let albedo = vec![Vec3::ONE; n];
        let normal = vec![Vec3::Z; n];
        let depth = vec![1.0; n];
        let out = filter(w, h, &gathered, &albedo, &normal, &depth, &DiscontinuitySettings::new(4, 1));
        // An interior pixel's 4×1 window holds each of the values 0..4 once: mean 1.5.
        assert!((out[2 * 8 + 3].x - 1.5).abs() < 1e-6);
    }
}
