//! The film: linear HDR accumulation with pixel filters, light-tracing splats and AOVs
//! (albedo, normal, depth, clamp compensation); image metrics and tone mapping.
//!
//! Drivers give each thread a [`FilmTile`] (disjoint pixel rectangles) and merge finished tiles
//! in a fixed order, so the image does not depend on the thread count. Splats (light tracing,
//! BDPT t = 1) land anywhere and are merged from per-tile lists, also in order.

pub mod filter;
pub mod image;
pub mod tonemap;

use glam::{DVec3, Vec2, Vec3};

pub use filter::{FilterKind, FilterSample, PixelFilter};
pub use image::{Image, ImageErrors};
pub use tonemap::{Tonemap, to_srgb8};

/// Accumulated samples of one pixel: Σ w·L and Σ w.
#[derive(Clone, Copy, Debug, Default)]
pub struct Pixel {
    /// Weighted radiance sum.
    pub sum: DVec3,
    /// Weight sum.
    pub weight: f64,
}

/// First-hit auxiliary values of one pixel (sums; divide by `count`).
#[derive(Clone, Copy, Debug, Default)]
pub struct AovPixel {
    /// Albedo sum.
    pub albedo: Vec3,
    /// Shading-normal sum.
    pub normal: Vec3,
    /// Depth (distance along the camera ray) sum.
    pub depth: f32,
    /// Clamp-compensation term sum (VPL modes with `--compensate on`; see
    /// [`crate::gather::compensate`]).
    pub compensation: Vec3,
    /// Number of samples summed.
    pub count: u32,
}

/// First-hit auxiliary values of a camera sample.
#[derive(Clone, Copy, Debug, Default)]
pub struct AovSample {
    /// Albedo of the first surface.
    pub albedo: Vec3,
    /// Its shading normal (facing the camera).
    pub normal: Vec3,
    /// Distance along the camera ray (0 for a miss).
    pub depth: f32,
    /// The radiance the clamp compensation added to the sample (zero where none).
    pub compensation: Vec3,
}

/// The AOV images of a film ([`Film::aov_images`]).
#[derive(Clone, Debug)]
pub struct AovImages {
    /// Mean albedo of the first surface.
    pub albedo: Image,
    /// Mean shading normal (normalised).
    pub normal: Image,
    /// Mean depth (in every channel).
    pub depth: Image,
    /// Mean clamp-compensation term (before the discontinuity buffer).
    pub compensation: Image,
}

/// A rectangle of pixels owned by one thread while it renders.
#[derive(Clone, Debug)]
pub struct FilmTile {
    /// Left column.
    pub x0: u32,
    /// Top row.
    pub y0: u32,
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Pixels, row-major.
    pub pixels: Vec<Pixel>,
    /// AOVs, row-major (empty when not requested).
    pub aovs: Vec<AovPixel>,
    /// Splats (raster position, value) collected while rendering this tile.
    pub splats: Vec<(Vec2, Vec3)>,
}

impl FilmTile {
    /// An empty tile.
    pub fn new(x0: u32, y0: u32, width: u32, height: u32, with_aovs: bool) -> Self {
        let n = (width * height) as usize;
        FilmTile {
            x0,
            y0,
            width,
            height,
            pixels: vec![Pixel::default(); n],
            aovs: if with_aovs { vec![AovPixel::default(); n] } else { Vec::new() },
            splats: Vec::new(),
        }
    }

    /// Adds a radiance sample with filter weight `w` to image pixel (x, y) of this tile.
    #[inline]
    pub fn add(&mut self, x: u32, y: u32, l: Vec3, w: f32) {
        let i = ((y - self.y0) * self.width + (x - self.x0)) as usize;
        let p = &mut self.pixels[i];
        p.sum += (l * w).as_dvec3();
        p.weight += w as f64;
    }

    /// Adds first-hit AOVs for image pixel (x, y).
    #[inline]
    pub fn add_aov(&mut self, x: u32, y: u32, a: &AovSample) {
        if self.aovs.is_empty() {
            return;
        }
        let i = ((y - self.y0) * self.width + (x - self.x0)) as usize;
        let p = &mut self.aovs[i];
        p.albedo += a.albedo;
        p.normal += a.normal;
        p.depth += a.depth;
        p.compensation += a.compensation;
        p.count += 1;
    }
}

/// The whole image being accumulated.
#[derive(Clone, Debug)]
pub struct Film {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// The reconstruction filter.
    pub filter: PixelFilter,
    pixels: Vec<Pixel>,
    aovs: Vec<AovPixel>,
    splats: Vec<DVec3>,
    /// Number of light-path sets per pixel that the splats average over.
    splat_passes: u64,
}

impl Film {
    /// A black film.
    pub fn new(width: u32, height: u32, filter: FilterKind, with_aovs: bool) -> Self {
        let n = width as usize * height as usize;
        Film {
            width,
            height,
            filter: PixelFilter::new(filter),
            pixels: vec![Pixel::default(); n],
            aovs: if with_aovs { vec![AovPixel::default(); n] } else { Vec::new() },
            splats: Vec::new(),
            splat_passes: 0,
        }
    }

    /// Square tiles of `size` pixels covering the image, in row-major order.
    pub fn tiles(&self, size: u32) -> Vec<(u32, u32, u32, u32)> {
        let mut t = Vec::new();
        for y in (0..self.height).step_by(size as usize) {
            for x in (0..self.width).step_by(size as usize) {
                t.push((x, y, size.min(self.width - x), size.min(self.height - y)));
            }
        }
        t
    }

    /// True when AOVs are accumulated.
    pub fn has_aovs(&self) -> bool {
        !self.aovs.is_empty()
    }

    /// Merges a finished tile (pixels, AOVs, and its splats).
    pub fn merge_tile(&mut self, tile: &FilmTile) {
        for j in 0..tile.height {
            for i in 0..tile.width {
                let src = (j * tile.width + i) as usize;
                let dst = ((tile.y0 + j) * self.width + tile.x0 + i) as usize;
                self.pixels[dst].sum += tile.pixels[src].sum;
                self.pixels[dst].weight += tile.pixels[src].weight;
                if !self.aovs.is_empty() && !tile.aovs.is_empty() {
                    let (a, b) = (&mut self.aovs[dst], &tile.aovs[src]);
                    a.albedo += b.albedo;
                    a.normal += b.normal;
                    a.depth += b.depth;
                    a.compensation += b.compensation;
                    a.count += b.count;
                }
            }
        }
        if !tile.splats.is_empty() {
            if self.splats.is_empty() {
                self.splats = vec![DVec3::ZERO; self.pixels.len()];
            }
            for (raster, v) in &tile.splats {
                let (x, y) = (raster.x as u32, raster.y as u32);
                if x < self.width && y < self.height && v.is_finite() {
                    self.splats[(y * self.width + x) as usize] += v.as_dvec3();
                }
            }
        }
    }

    /// Replaces each pixel's sum by `w`·(its sum) + (1 − w)·`other[i]`, where `other` holds
    /// per-pixel sums of as many unit-weight samples as the pixel's weight: the image becomes
    /// w·this + (1 − w)·(other's mean).
    pub fn blend_pixels(&mut self, other: &[DVec3], w: f64) {
        assert_eq!(self.pixels.len(), other.len(), "blended sums differ in size");
        for (p, o) in self.pixels.iter_mut().zip(other) {
            p.sum = p.sum * w + *o * (1.0 - w);
        }
    }

    /// Records that one more set of light paths (one per pixel on average) has been splatted.
    pub fn add_splat_pass(&mut self) {
        self.splat_passes += 1;
    }

    /// The current estimate: weighted pixel means plus splats averaged over their passes.
    pub fn image(&self) -> Image {
        let splat_scale = if self.splat_passes > 0 { 1.0 / self.splat_passes as f64 } else { 0.0 };
        let data = self
            .pixels
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let mut v = if p.weight != 0.0 { p.sum / p.weight } else { DVec3::ZERO };
                if !self.splats.is_empty() {
                    v += self.splats[i] * splat_scale;
                }
                let v = v.as_vec3();
                if v.is_finite() { v } else { Vec3::ZERO }
            })
            .collect();
        Image { width: self.width, height: self.height, data }
    }

    /// The AOV images, when accumulated.
    pub fn aov_images(&self) -> Option<AovImages> {
        if self.aovs.is_empty() {
            return None;
        }
        let blank = Image::new(self.width, self.height);
        let mut out =
            AovImages { albedo: blank.clone(), normal: blank.clone(), depth: blank.clone(), compensation: blank };
        for (i, p) in self.aovs.iter().enumerate() {
            if p.count > 0 {
                let c = p.count as f32;
                out.albedo.data[i] = p.albedo / c;
                out.normal.data[i] = p.normal.try_normalize().unwrap_or(Vec3::ZERO);
                out.depth.data[i] = Vec3::splat(p.depth / c);
                let comp = p.compensation / c;
                out.compensation.data[i] = if comp.is_finite() { comp } else { Vec3::ZERO };
            }
        }
        Some(out)
    }
}
