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
    let (x_lo, x_hi) = (s.n as i64 / 2, (s.n as i64 - 1) / 2);
    let (y_lo, y_hi) = (s.m as i64 / 2, (s.m as i64 - 1) / 2);
    // Irradiance-like quantity: gathered / albedo (per channel; zero albedo channels pass through).
    let ratio = |i: usize| -> Option<Vec3> {
        let a = albedo[i];
        if a.min_element() <= 0.0 { None } else { Some(gathered[i] / a) }
    };
    (0..height as i64)
        .into_par_iter()
        .flat_map_iter(|y| {
            (0..width as i64).map(move |x| {
                let i = (y * width as i64 + x) as usize;
                let (n0, d0) = (normal[i], depth[i]);
                let Some(r0) = ratio(i) else { return gathered[i] };
                if n0 == Vec3::ZERO || d0 <= 0.0 {
                    return gathered[i];
                }
                let mut sum = r0;
                let mut count = 1.0f32;
                for dy in -y_lo..=y_hi {
                    let yy = y + dy;
                    if yy < 0 || yy >= height as i64 {
                        continue;
                    }
                    for dx in -x_lo..=x_hi {
                        let xx = x + dx;
                        if (dx == 0 && dy == 0) || xx < 0 || xx >= width as i64 {
                            continue;
                        }
                        let j = (yy * width as i64 + xx) as usize;
                        if normal[j].dot(n0) < cos_max || (depth[j] - d0).abs() > s.max_relative_depth * d0 {
                            continue;
                        }
                        if let Some(r) = ratio(j) {
                            sum += r;
                            count += 1.0;
                        }
                    }
                }
                sum / count * albedo[i]
            })
        })
        .collect()
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
