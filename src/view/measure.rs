//! Measures of the frame loop: flicker between consecutive frames and convergence of the
//! accumulated image towards a reference.
//!
//! **Flicker** (issue 7; papers/002 §8 names flicker as MIR's limit). For consecutive
//! *individual* frames F_{t−1}, F_t (not the accumulated image), with luminances Y:
//!
//! ```text
//! d_t = mean over pixels of |Y_t − Y_{t−1}| / (Y_{t−1} + ε),   ε = 0.01 · ½ (mean Y_t + mean Y_{t−1})
//! flicker = mean over t = 1 … N−1 of d_t
//! ```
//!
//! ε is relative to the frames' mean luminance so that the measure does not depend on the
//! scene's units and dark pixels do not dominate it; taking it over both frames keeps d_t
//! finite (≤ 200) when the previous frame is black, and two black frames give 0. 0 means
//! identical frames; independent
//! noisy frames of the same view give a value set by the per-frame noise. For a moving camera
//! d_t also contains the image change due to the motion itself, the same with and without
//! chain reuse, so the two are compared on the same path.
//!
//! **Convergence.** The relative MSE of the accumulated image against a reference (mean over
//! pixels and channels of (x − r)² / (r² + 0.01), [`crate::film::ImageErrors`]) after
//! 1, 2, 4, 8, … frames.

use glam::Vec3;
use rayon::prelude::*;

use crate::color::luminance;

/// ε of the flicker measure, as a fraction of the two frames' mean luminance.
pub const FLICKER_EPSILON: f64 = 0.01;

fn luminances(image: &[Vec3]) -> Vec<f32> {
    image.par_iter().map(|&p| if p.is_finite() { luminance(p).max(0.0) } else { 0.0 }).collect()
}

/// The mean relative difference d_t between the luminances of two consecutive frames.
pub fn relative_difference(current: &[f32], previous: &[f32]) -> f64 {
    assert_eq!(current.len(), previous.len(), "frames differ in size");
    if previous.is_empty() {
        return 0.0;
    }
    let n = previous.len() as f64;
    let mean = |v: &[f32]| v.par_iter().map(|&y| y as f64).sum::<f64>() / n;
    let eps = FLICKER_EPSILON * 0.5 * (mean(current) + mean(previous));
    if !(eps > 0.0) {
        return 0.0;
    }
    current
        .par_iter()
        .zip(previous.par_iter())
        .map(|(&c, &p)| (c as f64 - p as f64).abs() / (p as f64 + eps))
        .sum::<f64>()
        / n
}

/// Running flicker measure over a sequence of frames.
#[derive(Clone, Debug, Default)]
pub struct FlickerMeter {
    previous: Option<Vec<f32>>,
    sum: f64,
    pairs: u32,
}

impl FlickerMeter {
    /// Adds the next individual frame; returns d_t when there was a previous frame of the
    /// same size (a size change starts a new sequence).
    pub fn push(&mut self, frame: &[Vec3]) -> Option<f64> {
        let y = luminances(frame);
        let d = match &self.previous {
            Some(prev) if prev.len() == y.len() => Some(relative_difference(&y, prev)),
            _ => None,
        };
        if let Some(d) = d {
            self.sum += d;
            self.pairs += 1;
        }
        self.previous = Some(y);
        d
    }

    /// Mean of d_t over the pairs seen so far.
    pub fn mean(&self) -> Option<f64> {
        (self.pairs > 0).then(|| self.sum / self.pairs as f64)
    }

    /// Number of frame pairs measured.
    pub fn pairs(&self) -> u32 {
        self.pairs
    }
}

/// True for the frame counts at which convergence is reported: 1, 2, 4, 8, …
pub fn is_checkpoint(frames: u64) -> bool {
    frames.is_power_of_two()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flicker_is_zero_for_identical_frames_and_follows_its_definition() {
        let mut m = FlickerMeter::default();
        let a = vec![Vec3::ONE; 8];
        assert_eq!(m.push(&a), None);
        assert_eq!(m.push(&a), Some(0.0));
        // Doubling every pixel: |2 − 1| / (1 + 0.01 · 1.5) per pixel.
        let b = vec![Vec3::splat(2.0); 8];
        let d = m.push(&b).unwrap();
        assert!((d - 1.0 / 1.015).abs() < 1e-9, "{d}");
        assert!((m.mean().unwrap() - 0.5 / 1.015).abs() < 1e-9);
        assert_eq!(m.pairs(), 2);
        // Black frames: 0 after 0, bounded after a cut to light.
        let black = vec![Vec3::ZERO; 8];
        assert!(m.push(&black).unwrap() < 1.0);
        assert_eq!(m.push(&black), Some(0.0));
        assert!((m.push(&a).unwrap() - 200.0).abs() < 1e-9);
    }

    #[test]
    fn flicker_does_not_depend_on_the_scene_units() {
        let a: Vec<f32> = (0..100).map(|i| (i % 7) as f32 * 0.3).collect();
        let b: Vec<f32> = (0..100).map(|i| (i % 5) as f32 * 0.4).collect();
        let d1 = relative_difference(&a, &b);
        let s = 1e-6f32;
        let d2 = relative_difference(
            &a.iter().map(|x| x * s).collect::<Vec<_>>(),
            &b.iter().map(|x| x * s).collect::<Vec<_>>(),
        );
        assert!((d1 - d2).abs() < 1e-4 * d1, "{d1} vs {d2}");
    }

    #[test]
    fn checkpoints_are_powers_of_two() {
        let c: Vec<u64> = (1..=20).filter(|&f| is_checkpoint(f)).collect();
        assert_eq!(c, [1, 2, 4, 8, 16]);
    }
}
