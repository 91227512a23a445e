//! The discontinuity buffer (Wald, Kollig, Benthin, Keller & Slusallek 2002; papers/002 §7.2):
//! each pixel averages gathered / albedo over the n×m window around it, using only neighbours
//! on the same continuous surface (normals within an angle, depths within a relative tolerance),
//! then multiplies by its own albedo. With an n×m interleave pattern every window holds each VPL
//! subset once, so a pixel inside a continuous surface sees all VPLs; texture detail stays sharp
//! (it is in the albedo), and nothing leaks across edges.

use glam::Vec3;
use rayon::prelude::*;

use crate::simd::{F8, Lanes};

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
    // Per row, 7 planes of `pw` floats: normal x, y, z, depth, and the irradiance-like ratio
    // gathered / albedo (x, y, z). A pixel that neither gives nor takes (a zero albedo channel)
    // has depth NaN, which fails every depth test. Rows are padded with LANES such pixels so
    // that 8-wide loads stay inside the row.
    let pw = w + F8::LANES;
    let mut planes = vec![0.0f32; PLANES * pw * h];
    planes.par_chunks_mut(PLANES * pw).enumerate().for_each(|(y, row)| {
        row[3 * pw..4 * pw].fill(f32::NAN);
        for x in 0..w {
            let i = y * w + x;
            let a = albedo[i];
            if a.min_element() <= 0.0 {
                continue;
            }
            let (n, r) = (normal[i], gathered[i] / a);
            for (k, v) in [n.x, n.y, n.z, depth[i], r.x, r.y, r.z].into_iter().enumerate() {
                row[k * pw + x] = v;
            }
        }
    });
    let mut out = vec![Vec3::ZERO; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let (y0, y1) = (y.saturating_sub(y_lo), (y + y_hi).min(h - 1));
        let (zero, one) = (F8::splat(0.0), F8::splat(1.0));
        for (x, o) in row.iter_mut().enumerate() {
            let i = y * w + x;
            let (n0, d0) = (normal[i], depth[i]);
            *o = gathered[i];
            if albedo[i].min_element() <= 0.0 || n0 == Vec3::ZERO || d0 <= 0.0 {
                continue;
            }
            let (nx, ny, nz) = (F8::splat(n0.x), F8::splat(n0.y), F8::splat(n0.z));
            let (d0v, tol, cos) = (F8::splat(d0), F8::splat(s.max_relative_depth * d0), F8::splat(cos_max));
            let (x0, x1) = (x.saturating_sub(x_lo), (x + x_hi).min(w - 1));
            // The window includes the pixel itself, which always passes its own test.
            let (mut sx, mut sy, mut sz, mut count) = (zero, zero, zero, zero);
            for yy in y0..=y1 {
                let base = yy * PLANES * pw;
                for xs in (x0..=x1).step_by(F8::LANES) {
                    let lanes = F8::first_lanes((x1 + 1 - xs).min(F8::LANES));
                    let at = |k: usize| F8::load(&planes[base + k * pw + xs..]);
                    let dot = at(0) * nx + at(1) * ny + at(2) * nz;
                    let keep = lanes.and(dot.ge(cos)).and((at(3) - d0v).abs().le(tol));
                    sx += keep.select(at(4), zero);
                    sy += keep.select(at(5), zero);
                    sz += keep.select(at(6), zero);
                    count += keep.select(one, zero);
                }
            }
            let count = count.sum_lanes(F8::ALL);
            let mean = if count > 0.0 {
                Vec3::new(sx.sum_lanes(F8::ALL), sy.sum_lanes(F8::ALL), sz.sum_lanes(F8::ALL)) / count
            } else {
                gathered[i] / albedo[i]
            };
            *o = mean * albedo[i];
        }
    });
    out
}

/// Planes per row of the filter's SoA copy of the G-buffer (normal xyz, depth, ratio xyz).
const PLANES: usize = 7;

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
