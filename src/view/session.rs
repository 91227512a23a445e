//! The per-frame core of the viewer, shared by the window and the headless loop: one VPL
//! sampler whose state persists across frames, [`frame::render_frame`] for each frame, and the
//! running mean of frames while the camera stands still.
//!
//! Temporal chain reuse (papers/002 §8, docs/design.md §3.6): when the camera changes, the sampler is
//! told whether the change was a small move (a stateful MIR sampler continues its chain) or a
//! jump (it starts afresh). A jump is a translation of more than [`JUMP_DISTANCE`] of the scene
//! diagonal, a turn of the view direction by more than [`JUMP_ANGLE_DEG`], a change of field of
//! view or resolution, or an explicit teleport (R reset). In "fresh chains" mode the sampler is
//! reset before every frame instead, which is the baseline of the flicker measure.
//! Stateless samplers (sir, sir-cdf, bir) ignore both calls.
//!
//! After a small move the session also reuses VPLs ([`super::reuse`]): the frame asks the
//! sampler for ⌈m/K⌉ new VPLs and gathers them pooled with the most recent VPLs of the previous
//! frame, m in all (K = [`SessionSettings::reuse_frames`]; 1, or fresh chains, turns it off).
//!
//! While the camera stands still, the G-buffer is traced every [`SessionSettings::gbuffer_frames`]-th
//! frame and held for the frames in between ([`GBufferUse`]): they differ from it only in their
//! VPLs, so they skip the camera rays and the receivers (a quarter of a frame's time on the
//! Cornell box). The anti-aliasing jitter then moves once per held G-buffer instead of every
//! frame; the running mean converges to the same image (each jittered position is uniform in
//! its pixel, as before). The jittered positions of a pixel step through a low-discrepancy sequence
//! ([`JitterSequence`]), so that fewer of them cover the pixel as evenly as independent ones
//! did every frame. The first frame after a change samples pixel centres; it and the next
//! K − 1 frames are traced and not held (the camera may move again, and the first frames after
//! it stops each take a new position, so the edges clean up as quickly as without holding).
//!
//! While the camera stands still, the next frame's VPLs are sampled during this frame's gather
//! ([`SessionSettings::ahead`]) when the sampler takes long enough to matter
//! ([`AHEAD_MIN_SAMPLING`]: the Metropolis samplers, sir-cdf, bir): both run at once on the
//! thread pool, so the cores that one leaves idle at its ends (the gather's last rows, the
//! chains' and the normalisation's last tasks) work on the other. They are sampled with the
//! seed and the sampler state the next frame would sample them with, so they are the same VPLs
//! and the frames the same pixels (tested).
//! A change before that frame (the camera moves, the settings or the sampler change) drops
//! them, and the frame samples its own; a Metropolis chain has then advanced one run further,
//! which changes which VPLs follow but not what they estimate.
//!
//! While the camera stands still the discontinuity buffer fades out of the image, as in
//! `render` ([`frame::Accumulation::filter_fade`]): the session keeps the running mean of the
//! frames as filtered and of the same frames unfiltered, and shows w·filtered + (1 − w)·
//! unfiltered with w = K/(K + N) after N frames ([`SessionSettings::filter_fade`]; `auto`:
//! K = n·m of the interleave tile). A moving camera (N = 1) sees the filtered frame; a still one
//! converges to the unbiased, unfiltered mean instead of the filter's blur of light that
//! changes within a window (the lit faces of a slit).

use std::time::{Duration, Instant};

use glam::Vec3;
use rayon::prelude::*;

use super::reuse;
use crate::accel::Accel;
use crate::frame::{self, FrameSettings, FrameStats};
use crate::gather::{CameraRays, GBufferUse, JitterSequence};
use clap::ValueEnum;

use crate::options::{FilterFade, SamplerConfig, VplSamplerArg};
use crate::sampling::rng::hash_words;
use crate::scene::{Camera, Scene};
use crate::vpl::{SamplerStats, VplSampler, VplSet};

/// A per-frame translation beyond this fraction of the scene diagonal is a jump.
pub const JUMP_DISTANCE: f32 = 0.1;
/// A per-frame turn of the view direction beyond this angle (degrees) is a jump.
pub const JUMP_ANGLE_DEG: f32 = 15.0;
/// VPLs are sampled ahead only for a sampler that took at least this long on the current
/// frame: a cheaper one (SIR, 0.1–0.2 ms) has nothing to hide behind the gather, and sampling it
/// ahead measured slower on Sponza (module doc).
pub const AHEAD_MIN_SAMPLING: Duration = Duration::from_millis(1);
/// Stream tag of frame seeds.
const TAG_VIEW_FRAME: u64 = 0x5649_4557;

/// How the camera changed since the previous frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motion {
    /// Not at all: frames keep accumulating.
    Still,
    /// A little: accumulation restarts, a Metropolis chain continues.
    Small,
    /// A jump: accumulation restarts, a Metropolis chain starts afresh.
    Jump,
}

/// Classifies the change from `prev` to `next` in a scene of diagonal `diagonal`.
pub fn classify_motion(prev: &Camera, next: &Camera, diagonal: f32) -> Motion {
    if prev == next {
        return Motion::Still;
    }
    let moved = prev.position.distance(next.position);
    let turned = prev.forward.dot(next.forward).clamp(-1.0, 1.0).acos().to_degrees();
    let reframed = (prev.width, prev.height) != (next.width, next.height)
        || (prev.fov_y_radians - next.fov_y_radians).abs().to_degrees() > JUMP_ANGLE_DEG;
    if reframed || !(moved <= JUMP_DISTANCE * diagonal) || !(turned <= JUMP_ANGLE_DEG) {
        Motion::Jump
    } else {
        Motion::Small
    }
}

/// The seed of frame `index` of a run seeded with `seed`.
pub fn frame_seed(seed: u64, index: u64) -> u64 {
    hash_words(&[seed, TAG_VIEW_FRAME, index])
}

/// The G-buffer of a frame that joins a running mean of `accumulated` frames while the camera
/// stands still, holding G-buffers for `every` frames (module doc). The first `every` frames
/// after a change (`accumulated` 0 … every − 1) are traced and not held, so the first frames
/// after the camera stops each take a new jitter position; then frames every, 2·every… trace and
/// hold, and the others reuse.
pub fn gbuffer_use(accumulated: u32, every: u32) -> GBufferUse {
    match accumulated {
        _ if every <= 1 => GBufferUse::Trace,
        a if a < every => GBufferUse::Trace,
        a if a % every == 0 => GBufferUse::TraceAndHold,
        _ => GBufferUse::Reuse,
    }
}

/// The index in a pixel's jitter sequence of a jittered frame (`accumulated` ≥ 1) under
/// [`gbuffer_use`]: one new position per traced G-buffer, so frames 1 … every − 1 take
/// positions 0 … every − 2 and a held G-buffer's frames share its position.
pub fn jitter_index(accumulated: u32, every: u32) -> u32 {
    let every = every.max(1);
    match accumulated {
        0 => 0,
        a if a < every => a - 1,
        a => every - 1 + (a - every) / every,
    }
}

/// The samplers `mirage view` starts with by preference: the first one built into this binary
/// is the default (so MTMH becomes the default as soon as it exists). Edit this line to change it.
pub const DEFAULT_SAMPLERS: [&str; 2] = ["mtmh", "sir"];

/// The default VPL sampler of the viewer (see [`DEFAULT_SAMPLERS`]).
pub fn default_sampler() -> VplSamplerArg {
    DEFAULT_SAMPLERS
        .iter()
        .find_map(|n| <VplSamplerArg as ValueEnum>::from_str(n, true).ok())
        .unwrap_or(VplSamplerArg::Sir)
}

/// The command-line name of a sampler (`sir-cdf`, `mtmh`...).
pub fn sampler_name(arg: VplSamplerArg) -> String {
    arg.to_possible_value().map(|v| v.get_name().to_string()).unwrap_or_else(|| format!("{arg:?}"))
}

/// What the viewer needs to start rendering.
#[derive(Clone, Debug, PartialEq)]
pub struct SessionSettings {
    /// The VPL sampler.
    pub sampler: VplSamplerArg,
    /// Maximum path depth of the sampler.
    pub max_depth: u32,
    /// The Metropolis samplers' settings (their `max_depth` is the one above).
    pub mir: SamplerConfig,
    /// The frame pipeline.
    pub frame: FrameSettings,
    /// Base seed; frame i uses [`frame_seed`]`(seed, i)`.
    pub seed: u64,
    /// Reset the sampler before every frame (no chain reuse, no VPL reuse).
    pub fresh_chains: bool,
    /// VPL reuse factor K after small moves: ⌈m/K⌉ new VPLs per frame (1: no reuse).
    pub reuse_frames: u32,
    /// While the camera stands still, trace the G-buffer every this many frames and gather the
    /// frames in between from it (1: trace every frame).
    pub gbuffer_frames: u32,
    /// While the camera stands still, when to sample the next frame's VPLs during this frame's
    /// gather (module doc).
    pub ahead: Ahead,
    /// How the discontinuity buffer fades out of the running mean while the camera stands
    /// still (module doc; `auto`: K = the interleave tile's pixel count, following it).
    pub filter_fade: FilterFade,
}

/// When a still camera's next VPLs are sampled during the current frame's gather.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Ahead {
    /// When the sampler took 1 ms or more on the current frame (`AHEAD_MIN_SAMPLING`).
    #[default]
    Auto,
    /// Whatever the sampler's time.
    Always,
    /// Never: each frame samples its VPLs when it starts (stage times add up to the frame).
    Never,
}

impl Ahead {
    /// Whether to sample ahead after a frame whose sampler took `sampler_time`.
    pub fn applies(self, sampler_time: Duration) -> bool {
        match self {
            Ahead::Auto => sampler_time >= AHEAD_MIN_SAMPLING,
            Ahead::Always => true,
            Ahead::Never => false,
        }
    }
}

impl SessionSettings {
    /// The sampler these settings choose, new.
    fn build_sampler(&self) -> Box<dyn crate::vpl::VplSampler> {
        self.sampler.build_with(&SamplerConfig { max_depth: self.max_depth, ..self.mir })
    }
}

impl Default for SessionSettings {
    /// `mirage view`'s defaults (its flags' defaults, tested there).
    fn default() -> Self {
        SessionSettings {
            sampler: default_sampler(),
            max_depth: 128,
            mir: SamplerConfig { max_depth: 128, ..SamplerConfig::default() },
            // The clamp compensated (key B), at one pixel in two: frame time.
            frame: FrameSettings { compensate: true, compensation_stride: 2, ..FrameSettings::interactive() },
            seed: 0,
            fresh_chains: false,
            reuse_frames: 4,
            gbuffer_frames: 4,
            ahead: Ahead::Auto,
            filter_fade: FilterFade::Auto,
        }
    }
}

/// One rendered frame as the loop sees it.
#[derive(Debug)]
pub struct FrameOutcome {
    /// The individual frame (linear radiance), before accumulation.
    pub image: Vec<Vec3>,
    /// Stage times and counts.
    pub stats: FrameStats,
    /// Time spent adding the frame to the running mean.
    pub accumulate_time: Duration,
    /// How the camera changed before this frame.
    pub motion: Motion,
    /// VPLs gathered (new and reused).
    pub vpls_gathered: usize,
    /// Of which reused from the previous frame.
    pub vpls_reused: usize,
    /// Non-finite pixels replaced by black (should stay 0).
    pub non_finite: usize,
    /// The VPLs were sampled during the previous frame's gather: `stats.vpl_time` overlapped it.
    pub vpls_ahead: bool,
}

/// Scene, BVH, sampler state and the accumulated image.
pub struct Session {
    scene: Scene,
    accel: Accel,
    sampler: Box<dyn VplSampler>,
    settings: SessionSettings,
    camera: Camera,
    pending: Motion,
    history: reuse::VplHistory,
    /// The previous frame's per-pixel buffers (G-buffer, light, filter planes, and the image
    /// once the frame loop hands it back), whose allocations the next frame reuses.
    spare: frame::Spare,
    frame_index: u64,
    /// The running mean of the frames as filtered.
    mean: Vec<Vec3>,
    /// While the filter fades: the running mean of the same frames unfiltered, and the image
    /// shown, the blend of the two (empty otherwise).
    unfiltered: Vec<Vec3>,
    shown: Vec<Vec3>,
    accumulated: u32,
    /// The next frame's VPLs, sampled during this frame's gather (still camera).
    ahead: Option<SampledAhead>,
}

/// VPLs sampled ahead for frame `frame_index`, the sampler's report on them and the time it took.
struct SampledAhead {
    frame_index: u64,
    vpls: VplSet,
    stats: SamplerStats,
    time: Duration,
}

impl Session {
    /// A session rendering `scene` through `camera`.
    pub fn new(scene: Scene, accel: Accel, camera: Camera, settings: SessionSettings) -> Self {
        let sampler = settings.build_sampler();
        Session {
            scene,
            accel,
            sampler,
            settings,
            mean: vec![Vec3::ZERO; camera.pixel_count()],
            unfiltered: Vec::new(),
            shown: Vec::new(),
            camera,
            pending: Motion::Jump,
            history: reuse::VplHistory::default(),
            spare: Default::default(),
            frame_index: 0,
            accumulated: 0,
            ahead: None,
        }
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The camera of the next frame.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// The current settings.
    pub fn settings(&self) -> &SessionSettings {
        &self.settings
    }

    /// Name of the active sampler.
    pub fn sampler_name(&self) -> &'static str {
        self.sampler.name()
    }

    /// Frames in the running mean.
    pub fn accumulated(&self) -> u32 {
        self.accumulated
    }

    /// Frames rendered since the start.
    pub fn frames_rendered(&self) -> u64 {
        self.frame_index
    }

    /// The image of the frames since the camera last changed (black before the first): their
    /// running mean, with the discontinuity buffer faded out over them
    /// ([`SessionSettings::filter_fade`]).
    pub fn mean(&self) -> &[Vec3] {
        if self.fading() { &self.shown } else { &self.mean }
    }

    /// The fade constant K in force: a fade is set and the filter is on.
    fn fade_constant(&self) -> Option<u32> {
        let f = &self.settings.frame;
        f.filter.and_then(|_| self.settings.filter_fade.constant(f.interleave))
    }

    /// While the filter fades: the weight of the filtered mean in the image shown, K/(K + N)
    /// after N frames.
    pub fn filter_weight(&self) -> Option<f64> {
        self.fading().then(|| frame::filter_weight(self.fade_constant(), self.accumulated))
    }

    /// Whether the image shown is a blend of the filtered and the unfiltered means.
    fn fading(&self) -> bool {
        self.fade_constant().is_some() && self.accumulated > 0
    }

    /// Moves the camera for the next frame; a change restarts accumulation and tells the
    /// sampler whether its chain may continue. Returns how the camera changed.
    pub fn set_camera(&mut self, camera: Camera) -> Motion {
        let motion = classify_motion(&self.camera, &camera, self.scene.bounds.diagonal());
        self.apply_motion(camera, motion);
        motion
    }

    /// Moves the camera and treats the change as a jump whatever its size (reset, cut).
    pub fn teleport(&mut self, camera: Camera) {
        self.apply_motion(camera, Motion::Jump);
    }

    fn apply_motion(&mut self, camera: Camera, motion: Motion) {
        if motion == Motion::Still {
            return;
        }
        self.ahead = None;
        self.sampler.camera_moved(motion == Motion::Jump);
        if camera.pixel_count() != self.mean.len() {
            self.mean = vec![Vec3::ZERO; camera.pixel_count()];
            (self.unfiltered, self.shown) = (Vec::new(), Vec::new());
        }
        self.camera = camera;
        self.accumulated = 0;
        self.pending = if self.pending == Motion::Jump { Motion::Jump } else { motion };
    }

    /// Replaces the sampler (a fresh one: chains do not carry over between strategies).
    pub fn set_sampler(&mut self, arg: VplSamplerArg) {
        self.settings.sampler = arg;
        self.sampler = self.settings.build_sampler();
        self.history.clear();
        self.restart();
    }

    /// Changes the frame pipeline settings; the image restarts, the chain continues.
    pub fn set_frame_settings(&mut self, frame: FrameSettings) {
        if frame != self.settings.frame {
            self.settings.frame = frame;
            self.restart();
        }
    }

    /// Switches between chain reuse and fresh chains every frame.
    pub fn set_fresh_chains(&mut self, fresh: bool) {
        self.settings.fresh_chains = fresh;
        self.restart();
    }

    /// Restarts accumulation without moving the camera.
    pub fn restart(&mut self) {
        self.accumulated = 0;
        self.ahead = None;
    }

    /// Takes back a frame's image ([`FrameOutcome::image`]) once it is no longer needed, for the
    /// next frame to write into instead of a fresh allocation.
    pub fn recycle(&mut self, image: Vec<Vec3>) {
        self.spare.image = image;
    }

    /// Renders the next frame (VPLs → G-buffer → gather → filter) and adds it to the mean.
    /// The same stages as [`frame::render_frame`], with the VPL reuse step between the sampler
    /// and the gather.
    pub fn step(&mut self) -> FrameOutcome {
        let motion = std::mem::replace(&mut self.pending, Motion::Still);
        let fresh = self.settings.fresh_chains;
        if fresh {
            self.sampler.reset();
        }
        if fresh || motion == Motion::Jump {
            self.history.clear();
        }
        let reuse = !fresh && motion == Motion::Small && self.settings.reuse_frames > 1;
        let m = self.settings.frame.vpls;
        let seed = frame_seed(self.settings.seed, self.frame_index);
        let mut stats = FrameStats::default();
        let t = Instant::now();
        let m_new = if reuse { reuse::new_vpls(m, self.settings.reuse_frames) } else { m };
        // VPLs sampled ahead during the previous frame's gather serve while nothing changed
        // since (any change dropped them).
        let ahead = self.ahead.take().filter(|a| a.frame_index == self.frame_index && motion == Motion::Still);
        let (ahead_time, overlapped) = (ahead.as_ref().map_or(Duration::ZERO, |a| a.time), ahead.is_some());
        let (new, sampler_stats) = match ahead {
            Some(a) => (a.vpls, a.stats),
            None => self.sampler.sample(&self.scene, &self.accel, &self.camera, m_new, seed),
        };
        let new_len = new.len();
        let keep_history = !fresh && self.settings.reuse_frames > 1;
        let (n, m_tile) = self.settings.frame.interleave;
        let vpls = if reuse {
            self.history.pool(new, m, (n * m_tile) as usize, self.frame_index)
        } else {
            if keep_history {
                self.history.restart(&new, self.frame_index);
            }
            new
        };
        stats.vpl_time = ahead_time + t.elapsed();
        stats.sampler = sampler_stats;
        let (vpls_gathered, vpls_reused) = (vpls.len(), vpls.len() - new_len);
        // Jitter (anti-aliasing) only frames that join a running mean: the first frame after a
        // change samples pixel centres, so a moving camera does not shimmer at edges.
        let mut settings = self.settings.frame;
        settings.jitter &= self.accumulated > 0;
        let k = self.settings.gbuffer_frames.max(1);
        let rays = CameraRays {
            gbuffer: gbuffer_use(self.accumulated, k),
            // The jittered G-buffers of a still camera step through one sequence per pixel.
            sequence: (self.accumulated > 0)
                .then(|| JitterSequence { seed: self.settings.seed, index: jitter_index(self.accumulated, k) }),
        };
        let sample_ahead = self.settings.ahead.applies(stats.sampler.time);
        let spare = std::mem::take(&mut self.spare);
        let (scene, accel, camera, sampler) = (&self.scene, &self.accel, &self.camera, &mut self.sampler);
        let gather = || frame::gather_frame_reusing(scene, accel, camera, vpls, &settings, seed, stats, spare, rays);
        // A still camera is likely still at the next frame: its VPLs (m new ones, as a still
        // frame takes) are sampled beside this gather, with the seed and the sampler state the
        // next frame would sample them with, so the same VPLs.
        let mut frame = if sample_ahead && !fresh && motion == Motion::Still {
            let index = self.frame_index + 1;
            let next_seed = frame_seed(self.settings.seed, index);
            let (frame, ahead) = rayon::join(gather, || {
                let t = Instant::now();
                let (vpls, stats) = sampler.sample(scene, accel, camera, m, next_seed);
                SampledAhead { frame_index: index, vpls, stats, time: t.elapsed() }
            });
            self.ahead = Some(ahead);
            frame
        } else {
            gather()
        };
        self.frame_index += 1;

        let t = Instant::now();
        self.accumulated += 1;
        let w = 1.0 / self.accumulated as f32;
        let non_finite = match self.fade_constant() {
            None => accumulate(&mut self.mean, &frame.image, w),
            Some(k) => {
                let n = self.mean.len();
                if self.unfiltered.len() != n {
                    self.unfiltered = vec![Vec3::ZERO; n];
                    self.shown = vec![Vec3::ZERO; n];
                }
                let blend = frame::filter_weight(Some(k), self.accumulated) as f32;
                let (light, emitted) = frame.unfiltered();
                accumulate_faded(
                    [&mut self.mean, &mut self.unfiltered, &mut self.shown],
                    [&frame.image, light, emitted],
                    w,
                    blend,
                )
            }
        };
        let accumulate_time = t.elapsed();
        // (The image leaves with the outcome; the frame loop hands it back, `Session::recycle`.)
        let (image, stats) = (std::mem::take(&mut frame.image), std::mem::take(&mut frame.stats));
        self.spare = frame.into_spare();
        FrameOutcome {
            image,
            stats,
            accumulate_time,
            motion,
            vpls_gathered,
            vpls_reused,
            non_finite,
            vpls_ahead: overlapped,
        }
    }
}

/// A finite value, or black (counted by the callers).
fn finite_or_black(x: Vec3) -> Vec3 {
    if x.is_finite() { x } else { Vec3::ZERO }
}

/// Adds `image` to the running `mean` with weight `w` (1 / frames); returns how many pixels
/// were not finite (taken as black).
fn accumulate(mean: &mut [Vec3], image: &[Vec3], w: f32) -> usize {
    mean.par_chunks_mut(4096)
        .zip(image.par_chunks(4096))
        .map(|(mean, img)| {
            let mut bad = 0;
            for (m, &x) in mean.iter_mut().zip(img) {
                bad += !x.is_finite() as usize;
                *m += (finite_or_black(x) - *m) * w;
            }
            bad
        })
        .sum()
}

/// [`accumulate`] for a fading filter: adds the filtered `image` to `mean` and the unfiltered
/// frame (`light + emitted`) to `unfiltered`, and writes `shown = blend·mean + (1 − blend)·
/// unfiltered`, in one pass. Returns how many filtered or unfiltered pixels were not finite.
fn accumulate_faded(
    [mean, unfiltered, shown]: [&mut [Vec3]; 3],
    [image, light, emitted]: [&[Vec3]; 3],
    w: f32,
    blend: f32,
) -> usize {
    const CHUNK: usize = 4096;
    mean.par_chunks_mut(CHUNK)
        .zip(unfiltered.par_chunks_mut(CHUNK))
        .zip(shown.par_chunks_mut(CHUNK))
        .zip(image.par_chunks(CHUNK).zip(light.par_chunks(CHUNK)).zip(emitted.par_chunks(CHUNK)))
        .map(|(((mean, unf), shown), ((img, light), emitted))| {
            let mut bad = 0;
            for (((m, u), s), ((&x, &l), &e)) in
                mean.iter_mut().zip(unf.iter_mut()).zip(shown.iter_mut()).zip(img.iter().zip(light).zip(emitted))
            {
                let y = l + e;
                bad += (!x.is_finite() || !y.is_finite()) as usize;
                *m += (finite_or_black(x) - *m) * w;
                *u += (finite_or_black(y) - *u) * w;
                *s = *u + (*m - *u) * blend;
            }
            bad
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam(eye: Vec3, target: Vec3) -> Camera {
        Camera::look_at(eye, target, Vec3::Y, 0.8, 16, 16)
    }

    #[test]
    fn small_moves_and_jumps_follow_the_thresholds() {
        let a = cam(Vec3::ZERO, Vec3::NEG_Z);
        assert_eq!(classify_motion(&a, &a.clone(), 10.0), Motion::Still);
        assert_eq!(classify_motion(&a, &cam(Vec3::X * 0.5, Vec3::X * 0.5 + Vec3::NEG_Z), 10.0), Motion::Small);
        assert_eq!(classify_motion(&a, &cam(Vec3::X * 1.5, Vec3::X * 1.5 + Vec3::NEG_Z), 10.0), Motion::Jump);
        let turned = |deg: f32| {
            let r = deg.to_radians();
            cam(Vec3::ZERO, Vec3::new(r.sin(), 0.0, -r.cos()))
        };
        assert_eq!(classify_motion(&a, &turned(10.0), 10.0), Motion::Small);
        assert_eq!(classify_motion(&a, &turned(20.0), 10.0), Motion::Jump);
        assert_eq!(classify_motion(&a, &a.clone().with_resolution(32, 16), 10.0), Motion::Jump);
    }

    #[test]
    fn a_still_camera_traces_its_gbuffer_every_k_frames() {
        use GBufferUse::*;
        let pattern: Vec<GBufferUse> = (0..10).map(|a| gbuffer_use(a, 3)).collect();
        assert_eq!(
            pattern,
            [Trace, Trace, Trace, TraceAndHold, Reuse, Reuse, TraceAndHold, Reuse, Reuse, TraceAndHold]
        );
        assert!((0..7).all(|a| gbuffer_use(a, 1) == Trace));
        // Every traced jittered frame takes the next position; reusing frames keep it.
        let index: Vec<u32> = (1..10).map(|a| jitter_index(a, 3)).collect();
        assert_eq!(index, [0, 1, 2, 2, 2, 3, 3, 3, 4]);
        assert!((1..7).all(|a| jitter_index(a, 1) == a - 1));
    }

    /// Through a session: a still camera's frames after the first K reuse the G-buffer (and
    /// equal frames traced with the holding frame's jitter: `gather::tests`); a camera that
    /// moves every frame never does, and a frame after a move traces.
    #[test]
    fn sessions_reuse_held_gbuffers_only_while_the_camera_stands_still() {
        use crate::accel::Accel;
        use crate::load::builtin;
        use crate::scene::{CameraSettings, Scene};
        let scene = Scene::from_desc(builtin::cornell(), &CameraSettings::default()).unwrap();
        let accel = Accel::build(&scene.mesh);
        let camera = scene.camera.clone().with_resolution(24, 16);
        let settings = SessionSettings {
            sampler: VplSamplerArg::Sir,
            max_depth: 8,
            frame: FrameSettings { vpls: 32, ..FrameSettings::interactive() },
            gbuffer_frames: 3,
            ..Default::default()
        };
        let mut s = Session::new(scene, accel, camera.clone(), settings);
        let reused = |s: &mut Session| {
            let o = s.step();
            assert!(o.image.iter().all(|p| p.is_finite()));
            let closest = o.stats.rays.closest;
            s.recycle(o.image);
            (o.stats.gbuffer_reused == 1, closest == 0)
        };
        let still: Vec<(bool, bool)> = (0..6).map(|_| reused(&mut s)).collect();
        let want = [false, false, false, false, true, true];
        assert_eq!(still, want.map(|r| (r, r)), "reused frames, and frames without camera rays");
        for k in 1..5 {
            let e = camera.position + Vec3::X * 0.001 * k as f32;
            s.set_camera(Camera::look_at(e, e + camera.forward, Vec3::Y, camera.fov_y_radians, 24, 16));
            assert_eq!(reused(&mut s), (false, false), "moving frame {k}");
        }
        // (The last moving frame started the mean; the next two trace, the third traces and
        // holds.)
        for k in 1..4 {
            assert_eq!(reused(&mut s), (false, false), "still frame {k} after a move");
        }
        assert_eq!(reused(&mut s), (true, true));
    }

    /// While the filter fades, the image a still camera shows after N frames is, pixel by
    /// pixel, w·(the filtered session's mean) + (1 − w)·(the unfiltered session's), w = K/(K+N),
    /// through held G-buffers and VPLs sampled ahead; it follows an interleave change (auto),
    /// and a camera move starts it again from the filtered frame.
    #[test]
    fn a_fading_session_shows_the_blend_of_the_filtered_and_unfiltered_means() {
        use crate::accel::Accel;
        use crate::load::builtin;
        use crate::scene::{CameraSettings, Scene};
        let scene = Scene::from_desc(builtin::ajar_door_thick(), &CameraSettings::default()).unwrap();
        let camera = scene.camera.clone().with_resolution(32, 24);
        let session = |fade: FilterFade, filter: bool| {
            let interactive = FrameSettings::interactive();
            let frame = FrameSettings {
                vpls: 64,
                filter: interactive.filter.filter(|_| filter),
                compensate: true,
                ..interactive
            };
            let settings = SessionSettings {
                sampler: VplSamplerArg::Mtmh,
                max_depth: 16,
                frame,
                filter_fade: fade,
                ahead: Ahead::Always,
                ..Default::default()
            };
            Session::new(scene.clone(), Accel::build(&scene.mesh), camera.clone(), settings)
        };
        let (mut faded, mut filtered, mut unfiltered) =
            (session(FilterFade::Frames(5), true), session(FilterFade::Never, true), session(FilterFade::Auto, false));
        for n in 1..=12u32 {
            for s in [&mut faded, &mut filtered, &mut unfiltered] {
                let o = s.step();
                assert_eq!(o.non_finite, 0);
                s.recycle(o.image);
            }
            assert_eq!(faded.filter_weight(), Some(5.0 / (5.0 + n as f64)));
            let w = 5.0 / (5.0 + n as f32);
            assert_eq!((filtered.filter_weight(), unfiltered.filter_weight()), (None, None));
            let mut differs = 0;
            for ((x, f), u) in faded.mean().iter().zip(filtered.mean()).zip(unfiltered.mean()) {
                let want = w * *f + (1.0 - w) * *u;
                assert!(
                    (*x - want).abs().max_element() <= 1e-5 * (1.0 + want.max_element()),
                    "frame {n}: {x} vs {want}"
                );
                differs += ((*f - *u).abs().max_element() > 1e-4) as usize;
            }
            assert!(differs > 0, "the filter changed nothing: the test tests nothing");
        }
        // A move restarts the mean: its first frame is filtered with weight K/(K + 1).
        let e = camera.position + Vec3::X * 1e-3;
        faded.set_camera(Camera::look_at(e, e + camera.forward, Vec3::Y, camera.fov_y_radians, 32, 24));
        assert_eq!(faded.filter_weight(), None);
        let o = faded.step();
        faded.recycle(o.image);
        assert_eq!(faded.filter_weight(), Some(5.0f64 / 6.0));
        // Auto follows the interleave tile; the filter off, nothing fades.
        let mut auto = session(FilterFade::Auto, true);
        auto.set_frame_settings(FrameSettings { interleave: (4, 4), ..auto.settings().frame });
        let o = auto.step();
        auto.recycle(o.image);
        assert_eq!(auto.filter_weight(), Some(16.0f64 / 17.0));
        auto.set_frame_settings(FrameSettings { filter: None, ..auto.settings().frame });
        assert_eq!(auto.filter_weight(), None);
    }

    #[test]
    fn auto_samples_ahead_only_for_samplers_that_take_a_millisecond_or_more() {
        let ms = Duration::from_micros;
        assert!(!Ahead::Auto.applies(ms(200)) && !Ahead::Auto.applies(ms(999)));
        assert!(Ahead::Auto.applies(ms(1000)) && Ahead::Auto.applies(ms(9000)));
        assert!(Ahead::Always.applies(ms(0)) && !Ahead::Never.applies(ms(9000)));
    }

    #[test]
    fn frame_seeds_differ_between_frames_and_runs() {
        assert_ne!(frame_seed(0, 0), frame_seed(0, 1));
        assert_ne!(frame_seed(0, 1), frame_seed(1, 0));
        assert_eq!(frame_seed(7, 3), frame_seed(7, 3));
    }
}
