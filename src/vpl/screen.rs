//! Where MIR looks on the screen: a histogram of the image positions of the chains' camera
//! vertices ([`ScreenGuide`]), i.e. of the image the chains sample, mixed with a uniform
//! density. Camera ends of the bidirectional kernel (its independent samples estimating P_c,
//! and its camera-end regenerations) and the camera probes that measure each VPL's response P′
//! are drawn from it, each weighted by the uniform density over the mixture's, so every
//! estimate keeps its expectation whatever the histogram, and a position the histogram missed
//! weighs at most 1 / (uniform share).
//!
//! Why (issue 19): on `light-box-thick` at 1024×768, the box's lamp-lit inside seen through two
//! 6-cm holes covers 185 of 786 432 pixels (0.024 %) but holds 25 % of the image's light.
//! Uniform camera ends found it on about one of the 4096 samples that estimate P_c each frame,
//! so P̂_c's spread was 42 % a frame, the chains' starting states rarely lay there and their
//! share of states there swung 0–100 % from frame to frame (2 chains carried over frames; 25 %
//! is right), and uniform probes met those VPLs 0.24 times per batch of 1024, so their P̂′ rested
//! on a handful of hits. 97 % of the image's error was in those pixels, and MIR's error was 10×
//! SIR's at equal time.

use glam::Vec2;

use crate::sampling::Distribution1D;
use crate::scene::Camera;

/// Share of the uniform density in the mixtures built on a [`ScreenGuide`] (the bound on a
/// sample's weight is its inverse).
pub const UNIFORM_SHARE: f32 = 0.5;

/// A histogram of image positions over a grid of screen cells (module doc).
#[derive(Clone, Debug)]
pub struct ScreenGuide {
    bins: [u32; 2],
    histogram: Distribution1D,
    width: f32,
    height: f32,
}

impl ScreenGuide {
    /// The histogram of `rasters` over about 64 cells across `camera`'s image (fewer for
    /// images under 64 pixels wide); `None` when no raster lies in the image.
    pub fn new(camera: &Camera, rasters: &[Vec2]) -> Option<Self> {
        let (width, height) = (camera.width as f32, camera.height as f32);
        let bx = camera.width.clamp(1, 64);
        let by = ((bx as f32 * height / width).round() as u32).clamp(1, camera.height.max(1));
        let mut counts = vec![0.0f64; (bx * by) as usize];
        let mut guide = ScreenGuide { bins: [bx, by], histogram: Distribution1D::new(&[1.0])?, width, height };
        for &r in rasters {
            if let Some(c) = guide.cell(r) {
                counts[c] += 1.0;
            }
        }
        guide.histogram = Distribution1D::new(&counts)?;
        Some(guide)
    }

    /// The cell holding `raster`, when it lies in the image.
    fn cell(&self, raster: Vec2) -> Option<usize> {
        let [bx, by] = self.bins;
        let (x, y) = (raster.x / self.width * bx as f32, raster.y / self.height * by as f32);
        if !(x >= 0.0 && y >= 0.0 && x.is_finite() && y.is_finite()) {
            return None;
        }
        Some(((y as u32).min(by - 1) * bx + (x as u32).min(bx - 1)) as usize)
    }

    /// The histogram's density at `raster` over the uniform density (1 where the histogram is
    /// flat, 0 where it is empty).
    pub fn relative_density(&self, raster: Vec2) -> f32 {
        let [bx, by] = self.bins;
        self.cell(raster).map_or(0.0, |c| self.histogram.pmf(c) * (bx * by) as f32)
    }

    /// A position drawn from the histogram: a cell chosen by `u_cell`, uniform inside it by
    /// `u`.
    pub fn sample(&self, u_cell: f32, u: Vec2) -> Vec2 {
        let c = self.histogram.sample(u_cell.min(1.0 - f32::EPSILON)).index as u32;
        let [bx, by] = self.bins;
        let x = ((c % bx) as f32 + u.x) / bx as f32 * self.width;
        let y = ((c / bx) as f32 + u.y) / by as f32 * self.height;
        Vec2::new(x.min(self.width * (1.0 - f32::EPSILON)), y.min(self.height * (1.0 - f32::EPSILON)))
    }

    /// The one-sample mixture's density at `raster` over the uniform density:
    /// [`UNIFORM_SHARE`] + (1 − [`UNIFORM_SHARE`]) · [`Self::relative_density`].
    pub fn mixture_factor(&self, raster: Vec2) -> f32 {
        UNIFORM_SHARE + (1.0 - UNIFORM_SHARE) * self.relative_density(raster)
    }

    /// A position from the one-sample mixture (uniform with probability [`UNIFORM_SHARE`]):
    /// `u` three uniform numbers.
    pub fn sample_mixture(&self, u: [f32; 3]) -> Vec2 {
        if u[0] < UNIFORM_SHARE {
            Vec2::new(u[1] * self.width, u[2] * self.height)
        } else {
            let u_cell = (u[0] - UNIFORM_SHARE) / (1.0 - UNIFORM_SHARE);
            self.sample(u_cell, Vec2::new(u[1], u[2]))
        }
    }
}

/// Where a batch of camera probes goes: `uniform` of them stratified over the image, the other
/// `guided` stratified over a [`ScreenGuide`]. A probe's response is weighted with the
/// multi-sample balance heuristic of the two ([`ProbeDensity::weight`]), so the batch's
/// estimate of a VPL's response is unbiased whatever the guide.
#[derive(Clone, Debug)]
pub struct ProbeDensity {
    guide: Option<ScreenGuide>,
    /// Uniform probes per batch (a square number).
    pub uniform: usize,
    /// Probes drawn from the guide per batch.
    pub guided: usize,
    width: f32,
    height: f32,
}

impl ProbeDensity {
    /// `k` probes per batch on `camera`'s image, a share `guided` of them (at most 0.9) from
    /// `guide`; all uniform without one.
    pub fn new(camera: &Camera, k: usize, guided: f64, guide: Option<ScreenGuide>) -> Self {
        let guide = guide.filter(|_| guided > 0.0);
        let k = k.max(1);
        let share = if guide.is_some() { guided.clamp(0.0, 0.9) } else { 0.0 };
        let side = (((1.0 - share) * k as f64).sqrt().ceil() as usize).max(1);
        let uniform = side * side;
        let guided = if guide.is_some() { k.saturating_sub(uniform) } else { 0 };
        ProbeDensity { guide, uniform, guided, width: camera.width as f32, height: camera.height as f32 }
    }

    /// Side of the uniform probes' stratification grid.
    fn side(&self) -> usize {
        (self.uniform as f64).sqrt().round() as usize
    }

    /// Probes per batch.
    pub fn count(&self) -> usize {
        self.uniform + self.guided
    }

    /// Balance weight of a probe at `raster`: K / (K_u + K_h · npix · h(raster)), h the guide's
    /// density per pixel, so that (npix / K) Σ y·w over a batch estimates Σ y over the pixels
    /// without bias (1 for every probe when none is guided).
    pub fn weight(&self, raster: Vec2) -> f32 {
        match &self.guide {
            Some(g) if self.guided > 0 => {
                self.count() as f32 / (self.uniform as f32 + self.guided as f32 * g.relative_density(raster))
            }
            _ => 1.0,
        }
    }

    /// Image position of probe `i` of a batch from `u` (four uniform numbers): stratified
    /// uniform for the first [`Self::uniform`], then stratified over the guide's cells.
    pub fn raster(&self, i: usize, u: [f32; 4]) -> Vec2 {
        if i < self.uniform {
            let side = self.side();
            let (gx, gy) = ((i % side) as f32, (i / side) as f32);
            return Vec2::new((gx + u[0]) / side as f32 * self.width, (gy + u[1]) / side as f32 * self.height);
        }
        let g = self.guide.as_ref().expect("guided probes have a guide");
        g.sample((((i - self.uniform) as f32 + u[2]) / self.guided as f32).min(1.0), Vec2::new(u[0], u[1]))
    }

    /// Size of a uniform probe's stratification cell, in pixels.
    pub fn cell(&self) -> [u32; 2] {
        let side = self.side() as u32;
        [(self.width as u32).div_ceil(side), (self.height as u32).div_ceil(side)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;
    use crate::scene::{CameraSettings, Scene};

    fn camera() -> Camera {
        let desc = crate::load::builtin::by_name("cornell").expect("built in");
        Scene::from_desc(desc, &CameraSettings { width: Some(64), height: Some(48), ..Default::default() })
            .expect("scene")
            .camera
    }

    /// A function with a narrow bright spot and a dim floor: its sum over the pixels, estimated
    /// from guided probes (weighted) and from mixture samples (divided by the mixture factor),
    /// agrees with the exact integral within four standard errors of the estimate, which must
    /// resolve 0.5 %; the guide is deliberately off the spot in part.
    #[test]
    fn guided_estimates_keep_their_expectation() {
        let cam = camera();
        let (centre, r) = (Vec2::new(40.5, 10.5), 2.0f32);
        let f = |p: Vec2| if (p - centre).length() < r { 500.0 } else { 1.0 + p.x / 64.0 };
        // ∫(1 + x/64) over 64×48, minus the disk's share of it (its mean is the centre's
        // value), plus 500 over the disk.
        let disk = std::f64::consts::PI * (r as f64).powi(2);
        let exact = 64.0 * 48.0 * 1.5 - disk * (1.0 + 40.5 / 64.0) + 500.0 * disk;
        let rasters: Vec<Vec2> =
            (0..400).map(|i| if i % 4 == 0 { Vec2::new(10.0, 30.0) } else { Vec2::new(40.0, 10.0) }).collect();
        let guide = ScreenGuide::new(&cam, &rasters).expect("a guide");
        let npix = 64.0 * 48.0;
        let mut rng = Pcg32::from_words(&[7]);
        let density = ProbeDensity::new(&cam, 256, 0.5, Some(guide.clone()));
        assert_eq!(density.count(), 256);
        let batches = 40_000;
        let (mut probes, mut mixture) = (Vec::new(), Vec::new());
        for _ in 0..batches {
            let (mut probe_sum, mut mix_sum) = (0.0f64, 0.0f64);
            for i in 0..density.count() {
                let u = [rng.next_f32(), rng.next_f32(), rng.next_f32(), rng.next_f32()];
                let p = density.raster(i, u);
                probe_sum += (f(p) * density.weight(p)) as f64 * npix / density.count() as f64;
                let q = guide.sample_mixture([u[0], u[1], u[2]]);
                mix_sum += (f(q) / guide.mixture_factor(q)) as f64 * npix / density.count() as f64;
            }
            probes.push(probe_sum);
            mixture.push(mix_sum);
        }
        for (name, v) in [("probes", probes), ("mixture", mixture)] {
            let n = v.len() as f64;
            let mean = v.iter().sum::<f64>() / n;
            let se = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
            assert!(se < 0.005 * exact, "{name}: standard error {se} too large to resolve 0.5 % of {exact}");
            assert!((mean - exact).abs() < 4.0 * se, "{name}: {mean} ± {se} vs {exact}");
        }
    }
}
