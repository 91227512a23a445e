//! Offline estimators and their progressive driver.
//!
//! An estimator is a per-sample function of `&Scene`, `&Accel` and `&mut impl Sampler`
//! ([`pt::radiance`]); the driver ([`render_progressive`]) owns threads (rayon over tiles),
//! passes, the time / sample budget, progress and film writes. Every pixel sample draws from a
//! stream hashed from (seed, pixel, sample index) — padded scrambled Sobol numbers by default,
//! independent ones with `--sampler independent` — so the image is bit-identical at any thread
//! count for a sample budget.

pub mod bdpt;
pub mod mlt;
pub mod pssmlt;
pub mod pt;

use std::time::{Duration, Instant};

use crate::progress::Progress;
use glam::{Vec2, Vec3, vec2};
use rayon::prelude::*;

use crate::accel::Accel;
use crate::film::{AovSample, Film, FilmTile, FilterKind};
use crate::sampling::{PixelSampler, PixelSamplerKind, Sampler};
use crate::scene::Scene;
use crate::stats::RayStats;

/// When a progressive render stops.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    /// This many samples per pixel.
    Samples(u32),
    /// As many passes as fit in this wall-clock time (at least one).
    Time(Duration),
}

impl Budget {
    /// Sets `progress`'s length: passes, or milliseconds.
    pub fn start_progress(&self, progress: &dyn Progress) {
        match *self {
            Budget::Samples(n) => progress.set_length(n as u64),
            Budget::Time(t) => progress.set_length(t.as_millis().max(1) as u64),
        }
    }

    /// The progressive loop every mode shares: `pass(done)` renders one pass after `done` units
    /// (samples per pixel, or frames) and returns how many it added, until the budget, counted
    /// from `start`, is spent; `progress` follows. Returns the units done.
    pub fn drive(&self, start: Instant, progress: &dyn Progress, mut pass: impl FnMut(u32) -> u32) -> u32 {
        self.start_progress(progress);
        let mut done = 0u32;
        loop {
            done += pass(done);
            if self.spent(done, start, progress) {
                break;
            }
        }
        progress.finish();
        done
    }

    /// After `passes` passes of a run that began at `start`: moves `progress` on and tells
    /// whether the budget is spent.
    pub fn spent(&self, passes: u32, start: Instant, progress: &dyn Progress) -> bool {
        match *self {
            Budget::Samples(n) => {
                progress.set_position(passes as u64);
                passes >= n
            }
            Budget::Time(t) => {
                progress.set_position(start.elapsed().min(t).as_millis() as u64);
                start.elapsed() >= t
            }
        }
    }
}

/// Settings shared by the offline modes.
#[derive(Clone, Debug, PartialEq)]
pub struct OfflineSettings {
    /// When to stop.
    pub budget: Budget,
    /// Seed of every random stream.
    pub seed: u64,
    /// Maximum number of scattering events along a path.
    pub max_depth: u32,
    /// Pixel reconstruction filter.
    pub filter: FilterKind,
    /// Accumulate albedo / normal / depth AOVs.
    pub aovs: bool,
    /// The numbers pt and bdpt draw per pixel sample (scrambled Sobol by default).
    pub sampler: PixelSamplerKind,
}

impl OfflineSettings {
    /// Quick preview quality.
    pub fn preview() -> Self {
        OfflineSettings {
            budget: Budget::Samples(16),
            seed: 0,
            max_depth: 128,
            filter: FilterKind::Box,
            aovs: false,
            sampler: PixelSamplerKind::Sobol,
        }
    }

    /// Final quality.
    pub fn final_() -> Self {
        OfflineSettings { budget: Budget::Samples(1024), ..Self::preview() }
    }
}

/// What a render produced.
#[derive(Debug)]
pub struct RenderOutput {
    /// The accumulated film.
    pub film: Film,
    /// Ray and sample counts.
    pub stats: RayStats,
    /// Samples per pixel reached.
    pub spp: u32,
    /// Wall-clock time.
    pub elapsed: Duration,
}

/// Side length of the square tiles threads render.
pub const TILE: u32 = 16;

/// Renders with a per-pixel-sample function `sample_fn(scene, accel, raster, sampler, tile)
/// -> (radiance, aov, stats)` progressively until the budget is spent. `splats_per_pass`
/// tells the film that each pass also splats one light-path set per pixel (BDPT).
pub fn render_progressive<F>(
    scene: &Scene,
    settings: &OfflineSettings,
    progress: &dyn Progress,
    splats_per_pass: bool,
    sample_fn: F,
) -> RenderOutput
where
    F: Fn(Vec2, &mut PixelSampler, &mut FilmTile, &mut RayStats) -> (Vec3, AovSample) + Sync,
{
    let cam = &scene.camera;
    let mut film = Film::new(cam.width, cam.height, settings.filter, settings.aovs);
    let tiles = film.tiles(TILE);
    let start = Instant::now();
    let mut stats = RayStats::default();
    // Samples per pixel per pass: small passes keep time budgets tight.
    let per_pass = match settings.budget {
        Budget::Samples(n) => n.clamp(1, 4),
        Budget::Time(_) => 1,
    };
    let spp = settings.budget.drive(start, progress, |spp| {
        let count = match settings.budget {
            Budget::Samples(n) => per_pass.min(n - spp),
            Budget::Time(_) => per_pass,
        };
        stats += pixel_pass(scene, settings, &mut film, &tiles, spp..spp + count, &sample_fn);
        if splats_per_pass {
            for _ in 0..count {
                film.add_splat_pass();
            }
        }
        count
    });
    RenderOutput { film, stats, spp, elapsed: start.elapsed() }
}

/// One pass of [`render_progressive`]: pixel samples `samples` (their indices in each pixel's
/// sequence) of every pixel, tile by tile in parallel, merged into `film` in tile order.
pub fn pixel_pass<F>(
    scene: &Scene,
    settings: &OfflineSettings,
    film: &mut Film,
    tiles: &[(u32, u32, u32, u32)],
    samples: std::ops::Range<u32>,
    sample_fn: &F,
) -> RayStats
where
    F: Fn(Vec2, &mut PixelSampler, &mut FilmTile, &mut RayStats) -> (Vec3, AovSample) + Sync,
{
    let cam = &scene.camera;
    let filter = &film.filter;
    let results: Vec<(FilmTile, RayStats)> = tiles
        .par_iter()
        .map(|&(x0, y0, w, h)| {
            let mut tile = FilmTile::new(x0, y0, w, h, settings.aovs);
            let mut st = RayStats::default();
            for y in y0..y0 + h {
                for x in x0..x0 + w {
                    let pixel = (y as u64) * cam.width as u64 + x as u64;
                    for s in samples.clone() {
                        let mut sampler =
                            PixelSampler::for_pixel_sample(settings.sampler, settings.seed, pixel, s as u64);
                        let fs = filter.sample(sampler.next_2d());
                        let raster = vec2(x as f32 + 0.5, y as f32 + 0.5) + fs.offset;
                        let (l, aov) = sample_fn(raster, &mut sampler, &mut tile, &mut st);
                        st.samples += 1;
                        if l.is_finite() {
                            tile.add(x, y, l, fs.weight);
                        } else {
                            st.discarded += 1;
                            tile.add(x, y, Vec3::ZERO, fs.weight);
                        }
                        tile.add_aov(x, y, &aov);
                    }
                }
            }
            (tile, st)
        })
        .collect();
    let mut stats = RayStats::default();
    for (tile, st) in &results {
        film.merge_tile(tile);
        stats += *st;
    }
    stats
}

/// Renders `scene` with bidirectional path tracing.
pub fn render_bdpt(
    scene: &Scene,
    accel: &Accel,
    settings: &OfflineSettings,
    opts: &bdpt::BdptOptions,
    progress: &dyn Progress,
) -> RenderOutput {
    render_progressive(scene, settings, progress, true, |raster, sampler, tile, st| {
        bdpt::sample(scene, accel, raster, sampler, opts, tile, st)
    })
}

/// Renders `scene` with the reference path tracer.
pub fn render_pt(scene: &Scene, accel: &Accel, settings: &OfflineSettings, progress: &dyn Progress) -> RenderOutput {
    render_pt_of_length(scene, accel, settings, None, progress)
}

/// [`render_pt`] restricted to paths with a number of segments in the inclusive range `edges`.
pub fn render_pt_of_length(
    scene: &Scene,
    accel: &Accel,
    settings: &OfflineSettings,
    edges: Option<(u32, u32)>,
    progress: &dyn Progress,
) -> RenderOutput {
    render_pt_filtered(scene, accel, settings, &pt::PathFilter { edges, ..Default::default() }, progress)
}

/// [`render_pt`] restricted to the paths `filter` admits.
pub fn render_pt_filtered(
    scene: &Scene,
    accel: &Accel,
    settings: &OfflineSettings,
    filter: &pt::PathFilter,
    progress: &dyn Progress,
) -> RenderOutput {
    render_progressive(scene, settings, progress, false, |raster, sampler, _tile, st| {
        let ray = scene.camera.generate_ray(raster, sampler.next_2d());
        pt::radiance_of_length(scene, accel, ray, sampler, settings.max_depth, filter, st)
    })
}
