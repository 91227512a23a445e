//! One frame of the VPL pipeline, in flow order: VPL sampler → G-buffer (primary rays) →
//! interleaved gather (shadow rays) → discontinuity buffer → image. Shared by
//! `render --mode ir|mir` (which accumulates independent frames) and the interactive viewer.

use std::time::{Duration, Instant};

use crate::progress::Progress;
use glam::Vec3;
use rayon::prelude::*;

use crate::accel::Accel;
use crate::film::{AovSample, Film, FilmTile, FilterKind};
use crate::filter::{DiscontinuitySettings, Masks, PlaneLayout, filter_planes};
use crate::gather::{self, CameraRays, GBuffer, GatherEnergy, Gathered, Interleave, Lent, OnePass, Tracing};
use crate::offline::{Budget, RenderOutput};
use crate::sampling::rng::hash_words;
use crate::scene::{Camera, Scene};
use crate::stats::RayStats;
use crate::vpl::transfer::g_bound;
use crate::vpl::{SamplerStats, VplSampler, VplSet};

/// Stream tag of a frame's interleave rotation ([`Interleave::rotated`]).
const TAG_INTERLEAVE_ROTATION: u64 = 0x524f_5441_5445;

/// Settings of the VPL pipeline.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameSettings {
    /// VPLs per frame (m).
    pub vpls: usize,
    /// Interleave tile n×m.
    pub interleave: (u32, u32),
    /// G clamp in units of 1/(scene diagonal)² (0: no clamp).
    pub clamp: f32,
    /// Discontinuity-buffer thresholds, or `None` for no filtering.
    pub filter: Option<(f32, f32)>,
    /// Specular bounces followed by primary rays.
    pub max_specular: u32,
    /// Jitter primary rays inside pixels (accumulating frames then anti-aliases).
    pub jitter: bool,
    /// Skip VPLs closer than this to the receiver (0 for rendering). Tests use it to compare
    /// unclamped VPL estimates with the path tracer on a domain where both have finite
    /// variance (see `offline::pt::PathFilter`).
    pub min_distance: f32,
    /// Single rays or packets (and which shadow-ray grouping) in the G-buffer and gather.
    pub tracing: Tracing,
    /// Compensate the clamp: a short residual path per pixel adds back, in expectation, what
    /// the clamp removed ([`crate::gather::compensate`]).
    pub compensate: bool,
    /// Gather VPLs that light very few pixels of their interleave subset at every pixel of
    /// their screen region ([`Interleave::for_image`]): without it such VPLs show as bright
    /// 8×8 squares.
    pub spread_small_vpls: bool,
    /// Split a VPL whose path count exceeds this many times the median count into copies on
    /// several interleave subsets ([`gather::split_strong`]); 0: never.
    pub split_strong: f32,
    /// Measure how evenly the VPLs lit the image ([`FrameStats::power_ratios`]; `render`'s
    /// summary prints it). Off in the viewer: it made the shadow stage 15 % slower there
    /// (cornell, sir; benches/results/2026-12-05-vpl-power.md).
    pub vpl_power: bool,
    /// Keep each pixel's compensation term apart as well ([`Frame::compensation`]; for the
    /// EXR's `compensation` layer).
    pub compensation_aov: bool,
    /// Trace the compensation at one pixel in this many (a diagonal pattern whose phase changes
    /// with the frame's seed; 2: a checkerboard), its residual weighted by the stride: the same
    /// expectation at a fraction of the rays, with more variance for the filter to average
    /// (interleaved sampling of the residual, as the VPLs are interleaved). 1: every pixel.
    pub compensation_stride: u32,
}

impl FrameSettings {
    /// Interactive defaults: 256 VPLs, 8×8 interleaving, clamp 300, filter 20° / 5 %.
    ///
    /// Clamp 300 (× 1/diagonal²): at 1000 MTMH renders of the Cornell box showed bright 8×8
    /// patches along edges — MIR puts VPLs close to visible surfaces, and an edge pixel whose
    /// window the discontinuity buffer cannot average keeps its ×64 interleave-scaled, clamped
    /// contribution; 300 removes them for 1.6 % of the gathered energy (1000: 0.8 %, 100: 2.4 %).
    pub fn interactive() -> Self {
        FrameSettings {
            vpls: 256,
            interleave: (8, 8),
            clamp: 300.0,
            filter: Some((20.0, 0.05)),
            max_specular: 4,
            jitter: true,
            min_distance: 0.0,
            tracing: Tracing::default(),
            compensate: false,
            spread_small_vpls: true,
            split_strong: 4.0,
            vpl_power: false,
            compensation_aov: false,
            compensation_stride: 1,
        }
    }

    /// Unbiased settings: no clamp, no filter.
    pub fn unbiased(vpls: usize) -> Self {
        FrameSettings { vpls, clamp: 0.0, filter: None, ..Self::interactive() }
    }

    /// Unbiased settings with finite variance: the gather clamped at the bound of MIR's chain
    /// target ([`crate::vpl::mirpath::TARGET_CLAMP`]) and the clamp compensated, no filter.
    /// The expectation is that of [`FrameSettings::unbiased`]; MIR's VPLs then bring, on
    /// average, exactly the response their normalisation measured (see the MIR module doc).
    pub fn compensated(vpls: usize) -> Self {
        FrameSettings { clamp: crate::vpl::mirpath::TARGET_CLAMP, compensate: true, ..Self::unbiased(vpls) }
    }
}

/// Time and work of one frame, by stage.
#[derive(Clone, Debug, Default)]
pub struct FrameStats {
    /// What the VPL sampler reported.
    pub sampler: SamplerStats,
    /// VPL generation time.
    pub vpl_time: Duration,
    /// Primary rays / G-buffer time. The G-buffer and the gather run as one pass over bands of
    /// rows ([`gather::trace_and_gather`]): its wall time is split between this and
    /// `shadow_time` in proportion to the thread time each part took.
    pub primary_time: Duration,
    /// Gather (shadow rays and shading) time, including filling the filter's planes.
    pub shadow_time: Duration,
    /// The part of `shadow_time` the clamp compensation took.
    pub compensation_time: Duration,
    /// Filter time (the planes it reads were filled during the pass).
    pub filter_time: Duration,
    /// Rays of the G-buffer and the gather.
    pub rays: RayStats,
    /// Energy kept and removed by clamping.
    pub energy: GatherEnergy,
    /// Per frame, the largest luminance a VPL brought to the image over the median
    /// ([`gather::power_ratio`]), when [`FrameSettings::vpl_power`] asks; frames whose VPLs
    /// brought nothing have none.
    pub power_ratios: Vec<f32>,
    /// Frames gathered from a held G-buffer ([`gather::GBufferUse::Reuse`]), no camera rays
    /// traced.
    pub gbuffer_reused: u64,
}

impl std::ops::AddAssign<&FrameStats> for FrameStats {
    fn add_assign(&mut self, o: &FrameStats) {
        self.vpl_time += o.vpl_time;
        self.primary_time += o.primary_time;
        self.shadow_time += o.shadow_time;
        self.compensation_time += o.compensation_time;
        self.filter_time += o.filter_time;
        self.rays += o.rays;
        self.energy += o.energy;
        self.power_ratios.extend_from_slice(&o.power_ratios);
        self.gbuffer_reused += o.gbuffer_reused;
        self.sampler.candidates += o.sampler.candidates;
        self.sampler.kept += o.sampler.kept;
        self.sampler.paths += o.sampler.paths;
        self.sampler.accepted += o.sampler.accepted;
        self.sampler.proposed += o.sampler.proposed;
        self.sampler.rays += o.sampler.rays;
        self.sampler.time += o.sampler.time;
        for w in &o.sampler.warnings {
            if !self.sampler.warnings.contains(w) {
                self.sampler.warnings.push(w.clone());
            }
        }
    }
}

/// A frame's per-pixel buffers that the next frame of the same size can reuse instead of
/// allocating and clearing them (see [`gather_frame_reusing`]).
#[derive(Debug, Default)]
pub struct Spare {
    /// The G-buffer, the light and the filter's planes ([`gather::Lent`]).
    pub lent: Lent,
    /// The image ([`Frame::image`], the filter's output), when the frame's user hands it back.
    pub image: Vec<Vec3>,
    /// Which neighbours the discontinuity buffer's windows took ([`Masks`]), recorded for the
    /// G-buffer held in `lent` and the settings and size they were recorded with.
    pub masks: Option<(DiscontinuitySettings, (u32, u32), Vec<u16>)>,
}

/// A rendered frame.
#[derive(Debug)]
pub struct Frame {
    /// Final radiance per pixel (emission seen + filtered VPL light).
    pub image: Vec<Vec3>,
    /// The frame's G-buffer.
    pub gbuffer: GBuffer,
    /// The frame's other per-pixel buffers, for the next frame to reuse: pass
    /// [`Frame::into_spare`] to [`gather_frame_reusing`].
    pub scratch: Spare,
    /// The VPLs used.
    pub vpls: VplSet,
    /// Stage times and counts.
    pub stats: FrameStats,
    /// Each pixel's clamp-compensation term, before the filter (included in `image`), when
    /// [`FrameSettings::compensation_aov`] asked; empty otherwise.
    pub compensation: Vec<Vec3>,
}

impl Frame {
    /// The frame without the discontinuity buffer, per pixel: its gathered light (clamp
    /// compensation included) and the emission seen directly, to be added.
    pub fn unfiltered(&self) -> (&[Vec3], &[Vec3]) {
        (&self.scratch.lent.light, &self.gbuffer.emitted)
    }

    /// The frame's buffers for the next frame to reuse (the G-buffer with them).
    pub fn into_spare(self) -> Spare {
        Spare {
            lent: Lent { gbuffer: self.gbuffer, ..self.scratch.lent },
            image: self.image,
            masks: self.scratch.masks,
        }
    }
}

/// Renders one frame with VPLs from `sampler`; `seed` selects the VPL set and the jitter.
pub fn render_frame(
    scene: &Scene,
    accel: &Accel,
    camera: &Camera,
    sampler: &mut dyn VplSampler,
    settings: &FrameSettings,
    seed: u64,
) -> Frame {
    render_frame_reusing(scene, accel, camera, sampler, settings, seed, Spare::default())
}

/// [`render_frame`] with the frame's buffers in the allocations of `spare` (see
/// [`gather_frame_reusing`]).
pub fn render_frame_reusing(
    scene: &Scene,
    accel: &Accel,
    camera: &Camera,
    sampler: &mut dyn VplSampler,
    settings: &FrameSettings,
    seed: u64,
    spare: Spare,
) -> Frame {
    let mut stats = FrameStats::default();
    let t = Instant::now();
    let (vpls, sstats) = sampler.sample(scene, accel, camera, settings.vpls, seed);
    stats.vpl_time = t.elapsed();
    stats.sampler = sstats;
    gather_frame_reusing(scene, accel, camera, vpls, settings, seed, stats, spare, CameraRays::default())
}

/// The frame pipeline after VPL sampling (G-buffer, gather, filter).
pub fn gather_frame(
    scene: &Scene,
    accel: &Accel,
    camera: &Camera,
    vpls: VplSet,
    settings: &FrameSettings,
    seed: u64,
    stats: FrameStats,
) -> Frame {
    gather_frame_reusing(scene, accel, camera, vpls, settings, seed, stats, Spare::default(), CameraRays::default())
}

/// [`gather_frame`] writing the G-buffer, the gathered light, the filter's planes and its
/// output into the allocations of `spare` (the previous frame's, [`Frame::into_spare`]) where
/// their sizes match: what a frame loop uses. They are not cleared (each is written before it
/// is read); allocating and zeroing them afresh cost ~1 ms a frame at 512². `camera_rays` says
/// whether to trace the G-buffer, and whether to hold it for, or reuse it from, another frame
/// through the same camera (`spare` carries what was held), and where jittered rays start.
pub fn gather_frame_reusing(
    scene: &Scene,
    accel: &Accel,
    camera: &Camera,
    vpls: VplSet,
    settings: &FrameSettings,
    seed: u64,
    mut stats: FrameStats,
    spare: Spare,
    camera_rays: CameraRays,
) -> Frame {
    let (n, m) = settings.interleave;
    // The gathered set: the sampler's, with its strong VPLs split (the frame keeps the
    // sampler's own for the viewer's reuse).
    let split = gather::split_strong(&vpls, settings.split_strong, (n, m), (camera.width, camera.height));
    let gathered_vpls = split.as_ref().unwrap_or(&vpls);
    let inter = if settings.spread_small_vpls {
        Interleave::for_image(gathered_vpls, n, m, (camera.width, camera.height))
    } else {
        Interleave::new(gathered_vpls, n, m)
    }
    .rotated(hash_words(&[seed, TAG_INTERLEAVE_ROTATION]));
    let filter = match settings.filter {
        Some((angle, depth)) if n * m > 1 => {
            Some(DiscontinuitySettings { n, m, max_normal_angle_deg: angle, max_relative_depth: depth })
        }
        _ => None,
    };
    // A held G-buffer's windows take the same neighbours every frame: the first frame that
    // filters it records which, the next ones take the record (the same image, bit for bit),
    // and their pass fills only the planes the record leaves to read.
    let size = (camera.width, camera.height);
    let (recorded, mut record) = match spare.masks {
        Some((s, wh, m)) => (Some(s) == filter && wh == size, m),
        None => (false, Vec::new()),
    };
    let pass = OnePass {
        camera,
        seed,
        jitter: settings.jitter,
        sequence: camera_rays.sequence,
        max_specular: settings.max_specular,
        tracing: settings.tracing,
        interleave: &inter,
        g_max: g_bound(scene, settings.clamp),
        min_distance: settings.min_distance,
        compensate: settings.compensate,
        compensation_aov: settings.compensation_aov,
        compensation_stride: settings.compensation_stride,
        planes: filter.map(|s| PlaneLayout::new(camera.width, &s)),
        gbuffer: camera_rays.gbuffer,
        ratio_planes_on_reuse: recorded,
        vpl_power: settings.vpl_power,
    };
    let Gathered {
        gbuffer: gbuf,
        light: gathered,
        energy,
        vpl_power,
        primary_time,
        shadow_time,
        compensation_time,
        compensation,
        planes,
        held,
        reused,
    } = gather::trace_and_gather(scene, accel, gathered_vpls, &pass, spare.lent, &mut stats.rays);
    stats.energy = energy;
    stats.power_ratios = gather::power_ratio(&vpl_power).into_iter().collect();
    stats.primary_time = primary_time;
    stats.shadow_time = shadow_time;
    stats.compensation_time = compensation_time;
    stats.gbuffer_reused = reused as u64;
    let t = Instant::now();
    // (The planes were filled during the pass: their time counts there.)
    // The image: filtered light plus the emission seen directly, written by the filter as it
    // goes.
    let mut masks = None;
    let (image, planes) = match (filter, pass.planes, planes) {
        (Some(s), Some(layout), Some(planes)) => {
            let (albedo, normal, depth, emitted) = (&gbuf.albedo, &gbuf.normal, &gbuf.depth, &gbuf.emitted);
            let reuse = spare.image;
            let use_masks = if reused && recorded {
                Masks::Apply(&record)
            } else if held.is_held() {
                Masks::Record(&mut record)
            } else {
                Masks::Test
            };
            let kept = !matches!(use_masks, Masks::Test);
            let image = filter_planes(
                &layout,
                &planes,
                gbuf.height,
                &gathered,
                albedo,
                normal,
                depth,
                &s,
                Some(emitted),
                reuse,
                use_masks,
            );
            if kept {
                masks = Some((s, size, record));
            }
            (image, planes)
        }
        (_, _, planes) => {
            let mut image = spare.image;
            if image.len() == gathered.len() {
                image.par_iter_mut().zip(&gathered).zip(&gbuf.emitted).for_each(|((i, g), e)| *i = *g + *e);
            } else {
                image = gathered.par_iter().zip(&gbuf.emitted).map(|(g, e)| *g + *e).collect();
            }
            (image, planes.unwrap_or_default())
        }
    };
    stats.filter_time = t.elapsed();
    let scratch =
        Spare { lent: Lent { gbuffer: GBuffer::default(), light: gathered, planes, held }, image: Vec::new(), masks };
    Frame { image, gbuffer: gbuf, vpls, stats, scratch, compensation }
}

/// How long and with which streams frames accumulate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Accumulation {
    /// N frames (`Samples(N)`) or a wall-clock budget.
    pub budget: Budget,
    /// Seed of the first frame; frame i uses a hash of (seed, i).
    pub seed: u64,
    /// Accumulate albedo / normal / depth AOVs.
    pub aovs: bool,
    /// Fade the discontinuity buffer out as frames accumulate, with this constant K: after N
    /// frames the image is w·(mean of the filtered frames) + (1 − w)·(mean of the same frames
    /// unfiltered), w = K / (K + N). `None`: the filtered mean throughout (the viewer's image).
    ///
    /// Why: the filter averages each pixel's interleaved VPL subset with its neighbours', which
    /// removes the interleave noise of a frame but blurs the light across each window. On a
    /// smooth surface the blur is harmless; where the light changes within a few pixels — the
    /// lit faces of a slit — it is a bias that accumulating frames never removes (measured on
    /// ajar-door-thick at 256×192: the lit door-frame strip 26 % dark, the image's nMSE stuck
    /// at 5.9 from 1 s to 16 s, against 1.3 unfiltered; benches/results/
    /// 2026-12-03-filter-converge-nmse.md). An unfiltered pixel has seen as many VPLs as one
    /// filtered frame after n·m frames, so K = n·m hands the image from the filter to the
    /// unbiased mean over about that many frames; w → 0, so the image converges to the
    /// unfiltered (unbiased) one.
    pub filter_fade: Option<u32>,
}

impl Accumulation {
    /// The filtered image's weight after `frames` frames ([`Accumulation::filter_fade`]).
    pub fn filter_weight(&self, frames: u32) -> f64 {
        filter_weight(self.filter_fade, frames)
    }
}

/// The filtered image's weight after `frames` frames with fade constant `fade`:
/// K / (K + N), 1 without a fade.
pub fn filter_weight(fade: Option<u32>, frames: u32) -> f64 {
    match fade {
        Some(k) => k as f64 / (k as f64 + frames as f64),
        None => 1.0,
    }
}

/// Accumulates independent frames (VPL sets) until the budget is spent: N frames for
/// `Budget::Samples(N)`, or as many as fit in the time.
pub fn render_progressive(
    scene: &Scene,
    accel: &Accel,
    sampler: &mut dyn VplSampler,
    settings: &FrameSettings,
    acc: Accumulation,
    progress: &dyn Progress,
) -> (RenderOutput, FrameStats) {
    let Accumulation { budget, seed, aovs, .. } = acc;
    let settings = &FrameSettings { compensation_aov: aovs && settings.compensate, ..*settings };
    let cam = &scene.camera;
    let mut film = Film::new(cam.width, cam.height, FilterKind::Box, aovs);
    // The unfiltered mean beside the filtered one, when the filter fades out.
    let fade = settings.filter.is_some() && acc.filter_fade.is_some();
    let mut unfiltered = vec![glam::DVec3::ZERO; if fade { cam.pixel_count() } else { 0 }];
    let start = Instant::now();
    let mut total = FrameStats::default();
    let mut spare = Spare::default();
    let frames = budget.drive(start, progress, |frames| {
        let frame_seed = seed.wrapping_mul(0x9e37_79b9).wrapping_add(frames as u64);
        let frame = render_frame_reusing(scene, accel, cam, sampler, settings, frame_seed, std::mem::take(&mut spare));
        let mut tile = FilmTile::new(0, 0, cam.width, cam.height, aovs);
        for y in 0..cam.height {
            for x in 0..cam.width {
                let i = (y * cam.width + x) as usize;
                tile.add(x, y, frame.image[i], 1.0);
                if aovs {
                    let g = &frame.gbuffer;
                    let compensation = frame.compensation.get(i).copied().unwrap_or_default();
                    let a = AovSample { albedo: g.albedo[i], normal: g.normal[i], depth: g.depth[i], compensation };
                    tile.add_aov(x, y, &a);
                }
            }
        }
        film.merge_tile(&tile);
        if fade {
            let (light, emitted) = frame.unfiltered();
            unfiltered.par_chunks_mut(4096).zip(light.par_chunks(4096).zip(emitted.par_chunks(4096))).for_each(
                |(u, (l, e))| {
                    for ((u, l), e) in u.iter_mut().zip(l).zip(e) {
                        *u += (*l + *e).as_dvec3();
                    }
                },
            );
        }
        total += &frame.stats;
        spare = frame.into_spare();
        total.rays.samples += (cam.width * cam.height) as u64;
        1
    });
    if fade {
        film.blend_pixels(&unfiltered, acc.filter_weight(frames));
    }
    let mut rays = total.rays;
    rays += total.sampler.rays;
    (RenderOutput { film, stats: rays, spp: frames, elapsed: start.elapsed() }, total)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gather::{GBufferUse, JitterSequence};
    use crate::load::builtin;
    use crate::progress::NoProgress;
    use crate::scene::CameraSettings;
    use crate::vpl::sir::Sir;

    /// Frames through a held G-buffer, the discontinuity buffer taking its windows' recorded
    /// neighbours, give the image of a frame traced afresh with the holding frame's seed and
    /// jitter and the new frame's VPLs and seed (which draws its interleave rotation), bit for
    /// bit; a traced frame in between drops the record.
    #[test]
    fn frames_from_a_held_gbuffer_equal_frames_traced_with_its_seed() {
        let scene = Scene::from_desc(builtin::cornell(), &CameraSettings::default()).unwrap();
        let accel = Accel::build(&scene.mesh);
        let camera = scene.camera.clone().with_resolution(40, 27);
        let settings = FrameSettings { interleave: (4, 4), ..FrameSettings::interactive() };
        let vpls = |seed: u64| Sir::new(4).sample(&scene, &accel, &camera, 64, seed).0;
        // Frame `index` of a still camera: its jitter is point `index` of the sequence.
        let frame_at = |vpls: VplSet, index: u32, seed: u64, spare: Spare, gbuffer: GBufferUse| {
            let rays = CameraRays { gbuffer, sequence: Some(JitterSequence { seed: 3, index }) };
            let stats = FrameStats::default();
            gather_frame_reusing(&scene, &accel, &camera, vpls, &settings, seed, stats, spare, rays)
        };
        let frame = |vpls: VplSet, index: u32, spare: Spare, gbuffer: GBufferUse| {
            frame_at(vpls, index, index as u64, spare, gbuffer)
        };
        // Traced with jitter point `index` and frame seed `seed`.
        let traced_at =
            |v: VplSet, index: u32, seed: u64| frame_at(v, index, seed, Spare::default(), GBufferUse::Trace).image;
        let traced = |v: VplSet, index: u32| traced_at(v, index, index as u64);
        let (a, b) = (vpls(1), vpls(2));
        let hold = frame(a.clone(), 5, Spare::default(), GBufferUse::TraceAndHold);
        assert!(hold.scratch.masks.is_some(), "the holding frame records its windows");
        assert!(hold.image == traced(a.clone(), 5));
        let first = frame(b.clone(), 6, hold.into_spare(), GBufferUse::Reuse);
        assert_eq!(first.stats.gbuffer_reused, 1);
        assert!(first.image == traced_at(b.clone(), 5, 6), "first reuse");
        let second = frame(a.clone(), 7, first.into_spare(), GBufferUse::Reuse);
        assert!(second.image == traced_at(a.clone(), 5, 7), "second reuse");
        assert!(second.image != traced(a.clone(), 7), "the jitter changes a traced frame");
        let plain = frame(b.clone(), 8, second.into_spare(), GBufferUse::Trace);
        assert!(plain.scratch.masks.is_none(), "a traced frame keeps no record");
        let again = frame(a.clone(), 9, plain.into_spare(), GBufferUse::Reuse);
        assert_eq!(again.stats.gbuffer_reused, 0);
        assert!(again.image == traced(a, 9));
    }

    /// A render whose filter fades out is, pixel by pixel, w·(the filtered render) + (1 − w)·(the
    /// unfiltered render) of the same seed, w = K/(K + N): the unfiltered mean it keeps is that
    /// of the same frames, and the weight is the documented one.
    #[test]
    fn a_faded_render_blends_the_filtered_and_unfiltered_renders() {
        let mut scene = Scene::from_desc(builtin::cornell(), &CameraSettings::default()).unwrap();
        scene.camera = scene.camera.clone().with_resolution(24, 16);
        let accel = Accel::build(&scene.mesh);
        let settings = FrameSettings { interleave: (4, 4), vpls: 32, ..FrameSettings::interactive() };
        let frames = 6;
        let run = |settings: &FrameSettings, fade: Option<u32>| {
            let acc = Accumulation { budget: Budget::Samples(frames), seed: 11, aovs: false, filter_fade: fade };
            render_progressive(&scene, &accel, &mut Sir::new(4), settings, acc, &NoProgress).0.film.image()
        };
        let filtered = run(&settings, None);
        let unfiltered = run(&FrameSettings { filter: None, ..settings }, None);
        let faded = run(&settings, Some(10));
        let w = 10.0 / (10.0 + frames as f32);
        assert!(filtered != unfiltered, "the filter changes the image");
        for ((f, u), x) in filtered.data.iter().zip(&unfiltered.data).zip(&faded.data) {
            let expected = *f * w + *u * (1.0 - w);
            assert!((*x - expected).abs().max_element() <= 1e-5 * (1.0 + expected.max_element()), "{x} ≠ {expected}");
        }
        let acc = Accumulation { budget: Budget::Samples(1), seed: 0, aovs: false, filter_fade: Some(64) };
        assert_eq!((acc.filter_weight(0), acc.filter_weight(64)), (1.0, 0.5));
        assert_eq!(Accumulation { filter_fade: None, ..acc }.filter_weight(1000), 1.0);
    }

    /// The compensation layer is each pixel's residual alone: the compensated frame minus it is
    /// the uncompensated frame of the same seed (the residual paths have their own streams),
    /// and its luminance sums to what the frame reports recovered.
    #[test]
    fn the_compensation_layer_is_what_compensation_added() {
        let scene = Scene::from_desc(builtin::cornell(), &CameraSettings::default()).unwrap();
        let accel = Accel::build(&scene.mesh);
        let camera = scene.camera.clone().with_resolution(24, 16);
        let base = FrameSettings { interleave: (4, 4), clamp: 30.0, filter: None, ..FrameSettings::interactive() };
        let run = |settings: FrameSettings| render_frame(&scene, &accel, &camera, &mut Sir::new(4), &settings, 9);
        let off = run(base);
        assert!(off.compensation.is_empty());
        let on = run(FrameSettings { compensate: true, compensation_aov: true, ..base });
        assert_eq!(on.compensation.len(), on.image.len());
        let (mut recovered, mut nonzero) = (0.0, 0);
        for ((a, b), c) in on.image.iter().zip(&off.image).zip(&on.compensation) {
            assert!((*a - *c - *b).abs().max_element() <= 1e-4 * (1.0 + b.max_element()), "{a} − {c} ≠ {b}");
            recovered += crate::color::luminance(*c) as f64;
            nonzero += (*c != Vec3::ZERO) as u32;
        }
        assert!(nonzero > 0 && off.stats.energy.removed > 0.0, "clamp 30 acts on the Cornell box");
        let r = on.stats.energy.recovered;
        assert!((recovered - r).abs() <= 1e-4 * r, "{recovered} vs {r}");
    }
}
