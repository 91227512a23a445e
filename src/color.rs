//! Colour leaf: linear Rec.709 RGB as `glam::Vec3`, luminance, and the sRGB transfer curve.

use glam::Vec3;

/// Luminance Y of linear Rec.709 RGB: the scalar target of every Metropolis chain.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// sRGB-encoded value in [0, 1] → linear.
#[inline]
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 { v / 12.92 } else { ((v + 0.055) / 1.055).powf(2.4) }
}

/// Linear value → sRGB-encoded value in [0, 1] (input clamped).
#[inline]
pub fn linear_to_srgb(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 }
}

/// True when every component is finite.
#[inline]
pub fn is_finite(c: Vec3) -> bool {
    c.x.is_finite() && c.y.is_finite() && c.z.is_finite()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips_and_white_has_unit_luminance() {
        for i in 0..=100 {
            let v = i as f32 / 100.0;
            assert!((linear_to_srgb(srgb_to_linear(v)) - v).abs() < 1e-5);
        }
        assert!((luminance(Vec3::ONE) - 1.0).abs() < 1e-6);
    }
}
